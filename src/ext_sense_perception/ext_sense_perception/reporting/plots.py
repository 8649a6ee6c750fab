"""The report's plots (matplotlib, headless)."""

from __future__ import annotations

from pathlib import Path

import matplotlib
import numpy as np

matplotlib.use("Agg")
import matplotlib.pyplot as plt
from matplotlib.ticker import NullFormatter, ScalarFormatter

from ext_sense_perception.reporting.scores import pareto_front


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
    yerr: list[float] | None = None,
) -> None:
    """Score against a time or rate axis as a PNG (error bars, labels, Pareto front optional)."""
    fig, ax = plt.subplots(figsize=(5, 3.4), dpi=110)
    order = np.argsort(xs)
    ax.errorbar(
        np.asarray(xs)[order],
        np.asarray(ys)[order],
        yerr=None if yerr is None else np.asarray(yerr)[order],
        fmt="o-" if labels is None else "o",
        color="C0",
        capsize=2,
        elinewidth=0.8,
    )
    if labels is not None:
        for x, y, s in zip(xs, ys, labels, strict=True):
            ax.annotate(s, (x, y), fontsize=6, xytext=(3, 3), textcoords="offset points")
    if pareto_lower is not None:
        front = pareto_front(xs, ys, pareto_lower)
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
