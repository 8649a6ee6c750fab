"""The fidelity figure (matplotlib, Agg backend): real sessions beside the scene.

Taps: the rate over the window (median and quartiles), its spectrum, the per-taxel rates by
rank, and each statistic per session. Food: events per second per class, the 10-bit values,
active taxels and events per trial.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ext_sense_sim.fidelity import food, taps
from ext_sense_sim.fidelity.check import SIMULATED, FidelityRun
from ext_sense_sim.fidelity.table import short_names

TAP_BOXES = (
    "events",
    "first_30ms",
    "last_100ms",
    "busiest_10",
    "finger_imbalance",
    "active_taxels",
    "half_peak_ms",
    "preroll_rate",
)
SIM_COLOUR = "C3"


def draw(run: FidelityRun, path: str | Path) -> Path:
    """Draw the run's figure to ``path`` (PNG; folders created) and return the path."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    result = run.result
    fig = _taps(plt, run) if result["kind"] == "tap" else _food(plt, run)
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=90)
    plt.close(fig)
    return path


def _groups(run: FidelityRun) -> tuple:
    """The run's result and tables, its real sessions, their short names, colours and order."""
    real = run.result["sessions"]
    colours = {name: f"C{i}" for i, name in enumerate(real)}
    colours[SIMULATED] = SIM_COLOUR
    return run.result, run.tables, real, short_names(real), colours, [*real, SIMULATED]


def _band(ax, x, rows: np.ndarray, colour: str, label: str, width: float = 2.0) -> None:
    p25, p50, p75 = np.percentile(rows, [25, 50, 75], axis=0)
    ax.plot(x, p50, color=colour, lw=width, label=label)
    ax.fill_between(x, p25, p75, color=colour, alpha=0.15, lw=0)


def _boxes(ax, groups: list[np.ndarray], labels: list[str], colours: list[str]) -> None:
    data = [g[np.isfinite(g)] for g in groups]
    parts = ax.boxplot(data, widths=0.6, showfliers=False, patch_artist=True)
    for patch, colour in zip(parts["boxes"], colours, strict=True):
        patch.set_facecolor(colour)
        patch.set_alpha(0.35)
    for i, (d, colour) in enumerate(zip(data, colours, strict=True)):
        jitter = np.random.default_rng(i).uniform(-0.15, 0.15, d.size)
        ax.scatter(np.full(d.size, i + 1.0) + jitter, d, s=6, color=colour, zorder=3)
    ax.set_xticks(range(1, len(labels) + 1), labels, rotation=20, fontsize=7)


def _taps(plt, run: FidelityRun):
    result, tables, real, short, colours, order = _groups(run)
    fig = plt.figure(figsize=(16, 10))
    grid = fig.add_gridspec(3, 4)
    ax = fig.add_subplot(grid[0, :2])
    t_ms = (np.arange(taps.WINDOW_BINS) + 0.5) * taps.BIN_S * 1e3
    pooled = np.vstack([tables[n].profiles for n in real]) / taps.BIN_S
    for n in real:
        ax.plot(
            t_ms,
            np.median(tables[n].profiles, 0) / taps.BIN_S,
            color=colours[n],
            lw=1,
            label=f"real {short[n]} ({len(tables[n].names)})",
        )
    _band(ax, t_ms, pooled, "k", f"real pooled ({len(pooled)})")
    _band(
        ax,
        t_ms,
        tables[SIMULATED].profiles / taps.BIN_S,
        SIM_COLOUR,
        f"simulated ({len(tables[SIMULATED].names)})",
    )
    ax.set_xlabel("time from the onset bin, ms (10 ms bins)")
    ax.set_ylabel("events per second")
    ax.set_title("rate over the window: median and quartiles")
    ax.legend(fontsize=8)
    ax = fig.add_subplot(grid[0, 2])
    freq = np.fft.rfftfreq(taps.WINDOW_BINS, taps.BIN_S)[1:]
    for name, rows in (("real pooled", pooled), ("simulated", tables[SIMULATED].profiles)):
        power = np.abs(np.fft.rfft(rows - rows.mean(1, keepdims=True), axis=1))[:, 1:] ** 2
        share = power / np.maximum(power.sum(1, keepdims=True), 1e-12)
        _band(ax, freq, share, "k" if name != "simulated" else SIM_COLOUR, name)
    ax.set_xlabel("Hz")
    ax.set_ylabel("share of the rate's AC power")
    ax.set_title("rate spectrum")
    ax.legend(fontsize=8)
    ax = fig.add_subplot(grid[0, 3])
    rank = np.arange(1, 81)
    for n in order:
        counts = -np.sort(-tables[n].taxel_counts, axis=1) / taps.WINDOW_S
        label = "simulated" if n == SIMULATED else f"real {short[n]}"
        ax.plot(rank, np.median(counts, 0), color=colours[n], label=label)
    ax.set_yscale("symlog", linthresh=10)
    ax.set_xlabel("taxel rank in the window")
    ax.set_ylabel("events per second (median)")
    ax.set_title("per-taxel rates")
    ax.legend(fontsize=8)
    labels = [short.get(n, n) for n in order]
    for k, stat in enumerate(TAP_BOXES):
        ax = fig.add_subplot(grid[1 + k // 4, k % 4])
        _boxes(ax, [tables[n].stats[stat] for n in order], labels, [colours[n] for n in order])
        ax.set_title(taps.STATS[stat], fontsize=9)
    verdict = {True: "targets pass", False: "targets FAIL"}[bool(result["pass"])]
    fig.suptitle(
        f"{result['scene']} vs real {result['rod_cm']} cm rod taps: {verdict} "
        f"(AUC {result['auc']['target']['sim_vs_pooled']:.2f})"
    )
    fig.tight_layout()
    return fig


def _food(plt, run: FidelityRun):
    result, tables, _, short, colours, order = _groups(run)
    labels = [short.get(n, n) for n in order]
    fig, axes = plt.subplots(2, 2, figsize=(13, 8))
    ax = axes[0, 0]
    classes = sorted({c for n in order for c in tables[n].labels})
    width = 0.8 / len(order)
    for j, n in enumerate(order):
        t = tables[n]
        for k, label in enumerate(classes):
            rates = t.stats["events_per_s"][np.array(t.labels) == label]
            x = np.full(rates.size, k - 0.4 + (j + 0.5) * width)
            ax.scatter(x, rates, s=10, color=colours[n], label=labels[j] if k == 0 else None)
    ax.set_xticks(range(len(classes)), classes, rotation=30, fontsize=8)
    ax.set_yscale("log")
    ax.set_ylabel("events per second after the motion start")
    ax.legend(fontsize=8)
    ax = axes[0, 1]
    bins = np.arange(0, 1025, 16)
    for n, label in zip(order, labels, strict=True):
        ax.hist(
            tables[n].values,
            bins=bins,
            density=True,
            histtype="step",
            color=colours[n],
            label=label,
        )
    ax.set_xlabel("value field (10 bit)")
    ax.set_ylabel("density")
    ax.legend(fontsize=8)
    for ax, stat in ((axes[1, 0], "active_taxels"), (axes[1, 1], "events")):
        _boxes(ax, [tables[n].stats[stat] for n in order], labels, [colours[n] for n in order])
        ax.set_title(food.STATS[stat], fontsize=9)
    fig.suptitle(f"{result['scene']} vs real food-poking sessions")
    fig.tight_layout()
    return fig
