"""The report's plots (matplotlib, headless)."""

from __future__ import annotations

from pathlib import Path

import matplotlib
import numpy as np

matplotlib.use("Agg")
import matplotlib.pyplot as plt
from matplotlib.ticker import NullFormatter, ScalarFormatter


def plot(
    path: Path,
    xs: list[float],
    ys: list[float],
    xlabel: str,
    ylabel: str,
    title: str,
    logx: bool = False,
    labels: list[str] | None = None,
    pareto_lower: bool | None = None,
) -> None:
    """Score against a time (or rate) axis as a PNG.

    Optionally labelled points and the Pareto front (``pareto_lower``: lower scores are better).
    """
    fig, ax = plt.subplots(figsize=(5, 3.4), dpi=110)
    order = np.argsort(xs)
    ax.plot(
        np.asarray(xs)[order], np.asarray(ys)[order], "o-" if labels is None else "o", color="C0"
    )
    if labels is not None:
        for x, y, s in zip(xs, ys, labels, strict=True):
            ax.annotate(s, (x, y), fontsize=6, xytext=(3, 3), textcoords="offset points")
    if pareto_lower is not None:
        front, best = [], None
        for i in order:
            y = ys[i]
            if best is None or (y < best if pareto_lower else y > best):
                best = y
                front.append(i)
        ax.plot(
            np.asarray(xs)[front],
            np.asarray(ys)[front],
            "-",
            color="C3",
            lw=1,
            label="Pareto front",
        )
        ax.legend(fontsize=7)
    if logx:
        ax.set_xscale("log")
        ax.xaxis.set_major_formatter(ScalarFormatter())
        ax.xaxis.set_minor_formatter(NullFormatter())
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.set_title(title, fontsize=9)
    ax.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)
