"""Event statistics of food poking: the simulated scene next to the real NUSkin captures.

Per trial: events per second (over the trial's span), active taxels (taxels with at least one
event) and the value field's distribution. Real captures are the lab's decoded ``.tact`` files
(``col0 taxel value t`` with first/last marker lines); simulated ones come from a run of
``food_fork_nuskin``. ``python -m ext_sense_sim.food_stats --real DIR --out PNG`` draws the
comparison (matplotlib, Agg backend) and prints the table.
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import NamedTuple

import numpy as np

from ext_sense_sim.errors import SceneError


class TrialStats(NamedTuple):
    """Statistics of one trial."""

    label: str
    events_per_s: float
    active_taxels: int
    values: np.ndarray


def read_tact(path: Path) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Taxel, value and time (s) of a decoded ``.tact`` file, markers dropped.

    Raises:
        SceneError: The file is unreadable or not four columns.
    """
    try:
        table = np.loadtxt(path, ndmin=2)
    except (OSError, ValueError) as err:
        raise SceneError(f"Cannot read .tact file {path}: {err}") from err
    if table.shape[1] != 4:
        raise SceneError(f"A .tact file has 4 columns; {path} has {table.shape[1]}.")
    body = table[1:-1]
    return body[:, 1].astype(int), body[:, 2].astype(int), body[:, 3]


def real_stats(folder: Path) -> list[TrialStats]:
    """Statistics of every ``<food>_zero_<n>.tact`` in ``folder`` (raw files skipped)."""
    out = []
    for path in sorted(Path(folder).glob("*_zero_*.tact")):
        if path.stem.endswith("_raw"):
            continue
        taxel, value, t = read_tact(path)
        span = t[-1] - t[0] if t.size > 1 else np.nan
        label = path.stem.split("_zero_")[0]
        out.append(TrialStats(label, taxel.size / span, int(np.unique(taxel).size), value))
    return out


def sim_stats(arrays: dict[str, np.ndarray], trial_s: float) -> list[TrialStats]:
    """Statistics of every trial of a simulated NUSkin dataset."""
    out = []
    bounds = np.searchsorted(arrays["ev_trial"], np.arange(arrays["trial"].size + 1))
    for i in range(arrays["trial"].size):
        sl = slice(bounds[i], bounds[i + 1])
        out.append(
            TrialStats(
                str(arrays["y"][i]),
                (bounds[i + 1] - bounds[i]) / trial_s,
                int(np.unique(arrays["ev_taxel"][sl]).size),
                arrays["ev_value"][sl],
            )
        )
    return out


def table(stats: list[TrialStats]) -> dict[str, tuple[float, float, float, float, float]]:
    """Per label: mean events/s, mean active taxels, value 5th/50th/95th percentiles."""
    out = {}
    for label in sorted({s.label for s in stats}):
        mine = [s for s in stats if s.label == label]
        values = np.concatenate([s.values for s in mine])
        p5, p50, p95 = np.percentile(values, [5, 50, 95]) if values.size else (np.nan,) * 3
        out[label] = (
            float(np.mean([s.events_per_s for s in mine])),
            float(np.mean([s.active_taxels for s in mine])),
            p5,
            p50,
            p95,
        )
    return out


def plot(real: list[TrialStats], sim: list[TrialStats], path: Path) -> Path:
    """Draw events/s per class and the value histograms, real beside simulated."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(11, 4))
    labels = sorted({s.label for s in real} | {s.label for s in sim})
    for offset, stats, name in ((-0.2, real, "real"), (0.2, sim, "simulated")):
        for k, label in enumerate(labels):
            rates = [s.events_per_s for s in stats if s.label == label]
            ax1.scatter(
                np.full(len(rates), k + offset),
                rates,
                s=12,
                color="C0" if name == "real" else "C1",
                label=name if k == 0 else None,
            )
    ax1.set_xticks(range(len(labels)), labels, rotation=30)
    ax1.set_yscale("log")
    ax1.set_ylabel("events per second")
    ax1.legend()
    bins = np.arange(0, 1025, 16)
    for stats, name in ((real, "real"), (sim, "simulated")):
        values = np.concatenate([s.values for s in stats])
        ax2.hist(values, bins=bins, density=True, histtype="step", label=name)
    ax2.set_xlabel("value field (10 bit)")
    ax2.set_ylabel("density")
    ax2.legend()
    fig.suptitle("NUSkin food poking: real captures vs food_fork_nuskin")
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return path


def main(argv: list[str] | None = None) -> int:
    """Run the comparison: simulate, read the real captures, print and plot."""
    from ext_sense_sim.dataset import DatasetCollector
    from ext_sense_sim.engine import Simulator
    from ext_sense_sim.scene import load_scene

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--real", required=True, help="folder of the real .tact captures")
    parser.add_argument("--out", required=True, help="PNG to write")
    parser.add_argument("--trials", type=int, default=28)
    args = parser.parse_args(argv)
    scene = load_scene("food_fork_nuskin")
    sim = Simulator(scene)
    collector = DatasetCollector(scene, scene.seed)
    for tb, signals in sim.batches(args.trials, scene.seed):
        collector.add(tb, signals)
    real, simulated = real_stats(Path(args.real)), sim_stats(collector.arrays(), scene.trial_s)
    for name, stats in (("real", real), ("simulated", simulated)):
        print(f"{name}: label events/s active_taxels value_p5 p50 p95")
        for label, row in table(stats).items():
            print(f"  {label:13s} " + " ".join(f"{x:8.1f}" for x in row))
    plot(real, simulated, Path(args.out))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
