"""One fidelity run: read the real sessions, simulate the scene, compare.

:func:`run_fidelity` returns the JSON-ready result (what ``--json`` writes) and the per-window
tables the figure is drawn from.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from itertools import combinations
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np

from ext_sense_runtime.enums import Task
from ext_sense_sim.fidelity import food, taps
from ext_sense_sim.fidelity.captures import (
    Capture,
    Session,
    check_kind,
    read_sessions,
    rod_cm,
    simulate,
)
from ext_sense_sim.fidelity.compare import (
    AUC_MARGIN,
    REPEATS,
    TAP_TARGETS,
    Target,
    summarise,
    two_sample_auc,
)
from ext_sense_sim.fidelity.errors import FidelityError
from ext_sense_sim.scene import Scene

DEFAULT_TRIALS = {Task.TAP_LOCALIZATION: 60, Task.FOOD_IDENTIFICATION: 35}
"""Simulated trials when ``--trials`` is not given: enough for stable medians in seconds."""
TAP_EXTRA_S = 0.1
"""Seconds added to each simulated tap trial so the 250 ms window fits after a late onset."""
CV_SEED = 0
"""Seed of the two-sample tests' folds and forests."""
SHOWN_REPEATS = 2
"""Cross-validation shuffles of the AUCs only shown (no target rests on them)."""
SIMULATED = "simulated"
POOLED = "real pooled"


Table = taps.TapWindows | food.FoodTrials


def pooled(tables: dict[str, Table], names: list[str]) -> dict[str, np.ndarray]:
    """The per-window statistics of the tables ``names``, pooled (the real sessions)."""
    return {k: np.concatenate([tables[n].stats[k] for n in names]) for k in tables[names[0]].stats}


class FidelityRun(NamedTuple):
    """A run's result (JSON-ready) and its tables by group (session names, ``simulated``)."""

    result: dict[str, Any]
    tables: dict[str, Table]


def run_fidelity(
    scene: Scene, real: list[str | Path], trials: int | None = None, seed: int | None = None
) -> FidelityRun:
    """Compare a NUSkin tap or food scene with the real captures under each folder of ``real``.

    Raises:
        FidelityError: No or unreadable real folders, two folders of one session, a session
            with no usable capture, or a scene without real kin.
    """
    task = check_kind(scene)
    if not real:
        raise FidelityError("Give at least one --real folder of real captures.")
    trials = DEFAULT_TRIALS[task] if trials is None else int(trials)
    seed = scene.seed if seed is None else int(seed)
    sessions = read_sessions(scene, real)
    names = [s.name for s in sessions]
    if len(set(names)) != len(names):
        raise FidelityError(f"The --real folders must be different sessions. Got {names}.")
    if task is Task.TAP_LOCALIZATION:
        sim = simulate(scene, trials, seed, TAP_EXTRA_S)
        return _compare(scene, sessions, sim, seed, taps.tap_windows, "tap")
    sim = simulate(scene, trials, seed)
    return _compare(scene, sessions, sim, seed, food.food_trials, "food")


def _compare(
    scene: Scene,
    sessions: list[Session],
    sim: Session,
    seed: int,
    describe: Callable[[list[Capture]], Table],
    kind: str,
) -> FidelityRun:
    """Describe every session and the simulated run alike, then summarise and compare."""
    tables = {s.name: describe(s.captures) for s in sessions}
    empty = [name for name, t in tables.items() if not t.names]
    if empty:
        raise FidelityError(
            f"Real session(s) {', '.join(empty)} hold no usable capture (every tap missed)."
        )
    tables[SIMULATED] = describe(sim.captures)
    if not tables[SIMULATED].names:
        raise FidelityError(f"No simulated trial of '{scene.name}' gave a window.")
    real_names = [s.name for s in sessions]
    pooled_stats = pooled(tables, real_names)
    groups: dict[str, Any] = {}
    for s in sessions:
        groups[s.name] = _group(tables[s.name], s.path, len(s.captures))
    groups[POOLED] = {"summary": summarise(pooled_stats), "windows": len(pooled_stats["events"])}
    if kind == "tap":
        groups[POOLED]["profile"] = _profile(np.vstack([tables[n].profiles for n in real_names]))
    groups[SIMULATED] = _group(tables[SIMULATED], sim.path, len(sim.captures))
    result: dict[str, Any] = {
        "scene": scene.name,
        "kind": kind,
        "trials": len(sim.captures),
        "seed": seed,
        "sessions": real_names,
        "groups": groups,
    }
    if kind == "tap":
        result["rod_cm"] = rod_cm(scene)
        err = tables[SIMULATED].onset_error_ms
        result["onset_error_ms_median"] = float(np.nanmedian(err)) if err.size else None
        result["targets"] = _targets(groups, real_names, TAP_TARGETS)
        result["auc"] = {
            "target": _auc(tables, real_names, taps.TARGET_FEATURES, each=True),
            "table": _auc(tables, real_names, taps.TABLE_FEATURES, False, SHOWN_REPEATS),
            "all": _auc(tables, real_names, taps.FEATURES, False, SHOWN_REPEATS),
        }
        checks = [t["pass"] for t in result["targets"]]
        if result["auc"]["target"]["pass"] is not None:
            checks.append(result["auc"]["target"]["pass"])
        result["pass"] = all(checks)
    else:
        result["span_s"] = food.SPAN_S
        result["per_class"] = _per_class(tables, real_names)
        result["auc"] = {"trial": _auc(tables, real_names, food.FEATURES, True, SHOWN_REPEATS)}
        result["pass"] = None
    return FidelityRun(result, tables)


def result_json(result: dict[str, Any]) -> str:
    """The result as strict JSON (NaN, e.g. an AUC with too few windows, becomes null)."""

    def clean(x: Any) -> Any:
        if isinstance(x, float) and not np.isfinite(x):
            return None
        if isinstance(x, dict):
            return {k: clean(v) for k, v in x.items()}
        if isinstance(x, list):
            return [clean(v) for v in x]
        return x

    return json.dumps(clean(result), indent=2, allow_nan=False) + "\n"


def _profile(profiles: np.ndarray) -> dict[str, list[float]]:
    p25, p50, p75 = np.percentile(profiles, [25, 50, 75], axis=0)
    return {"median": p50.tolist(), "p25": p25.tolist(), "p75": p75.tolist()}


def _group(table: Table, path: str, captures: int) -> dict[str, Any]:
    out: dict[str, Any] = {
        "path": path,
        "captures": captures,
        "windows": len(table.names),
        "cut_short": list(table.cut_short),
        "summary": summarise(table.stats),
    }
    if isinstance(table, taps.TapWindows):
        out["missed"] = list(table.missed)
        out["profile"] = _profile(table.profiles)
    return out


def _targets(groups: dict, real_names: list[str], targets: tuple[Target, ...]) -> list[dict]:
    sim = groups[SIMULATED]["summary"]
    out = []
    for t in targets:
        s = sim[t.stat]["median"]
        r = groups[POOLED]["summary"][t.stat]["median"]
        per = {}
        for name in real_names:
            rn = groups[name]["summary"][t.stat]["median"]
            per[name] = {"value": t.measure(rn, s), "pass": t.holds(rn, s)}
        out.append(
            {
                "stat": t.stat,
                "allowed": t.allowed(),
                "kind": t.kind,
                "real": r,
                "sim": s,
                "value": t.measure(r, s),
                "pass": t.holds(r, s),
                "per_session": per,
            }
        )
    return out


def _auc(
    tables: dict[str, Table],
    real_names: list[str],
    names: tuple[str, ...],
    each: bool,
    repeats: int = REPEATS,
) -> dict[str, Any]:
    """Two-sample AUCs on the statistics ``names`` and the target built on them.

    Sim vs pooled real (and vs each session when ``each``), and every pair of real sessions.
    The folds and forests have a seed of their own (:data:`CV_SEED`), so the real sessions'
    yardstick does not move with the simulation's seed.
    """
    rows = {
        name: np.column_stack([t.stats[s] for s in names]) if t.names else np.zeros((0, len(names)))
        for name, t in tables.items()
    }

    def auc(a: np.ndarray, b: np.ndarray) -> float:
        return two_sample_auc(a, b, CV_SEED, repeats)

    pairs = {f"{a} | {b}": auc(rows[a], rows[b]) for a, b in combinations(real_names, 2)}
    finite = [v for v in pairs.values() if np.isfinite(v)]
    yardstick = max(finite) if finite else None
    sim = rows[SIMULATED]
    vs_pooled = auc(sim, np.vstack([rows[n] for n in real_names]))
    per = {n: auc(sim, rows[n]) for n in real_names} if each else {}
    return {
        "statistics": list(names),
        "sim_vs_pooled": vs_pooled,
        "sim_vs_session": per,
        "real_vs_real": pairs,
        "yardstick": yardstick,
        "limit": None if yardstick is None else yardstick + AUC_MARGIN,
        "pass": None if yardstick is None else bool(vs_pooled <= yardstick + AUC_MARGIN),
    }


def _per_class(tables: dict[str, Table], real_names: list[str]) -> dict[str, dict[str, Any]]:
    """Events/s per food class present in both the real sessions and the scene."""

    def rates(names: list[str]) -> dict[str, list[float]]:
        out: dict[str, list[float]] = {}
        for n in names:
            t = tables[n]
            for label, rate in zip(t.labels, t.stats["events_per_s"], strict=True):
                out.setdefault(label, []).append(float(rate))
        return out

    real, sim = rates(real_names), rates([SIMULATED])
    return {
        label: {
            "real_median": float(np.median(real[label])),
            "real_n": len(real[label]),
            "sim_median": float(np.median(sim[label])),
            "sim_n": len(sim[label]),
        }
        for label in sorted(set(real) & set(sim))
    }
