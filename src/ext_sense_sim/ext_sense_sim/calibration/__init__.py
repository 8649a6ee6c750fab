"""Fitting a scene's physics to real captures: the search, the stages, one scene's run.

:mod:`.search` holds the generic deterministic coordinate search over a scene's free
parameters; :mod:`.stages` what each stage fits and how it measures a scene; this module runs a
scene's stages against real sessions (``ext-sense sim calibrate``; docs/simulator.md,
"Calibration against the real sensor").
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import yaml

from ext_sense_runtime.enums import Task
from ext_sense_sim.calibration.search import (
    FitStep,
    FreeParameter,
    Target,
    effect_lines,
    fit,
    start_values,
    with_values,
)
from ext_sense_sim.calibration.stages import (
    FOOD_FREE,
    FOOD_TOLERANCES,
    NOISE_FREE,
    NOISE_TOLERANCES,
    TAP_FREE,
    TAP_TOLERANCES,
    food_measure,
    noise_measure,
    real_quiet_stats,
    tap_measure,
    window_medians,
)
from ext_sense_sim.errors import SceneError
from ext_sense_sim.fidelity.captures import check_kind, read_food_session, read_tap_session, rod_cm
from ext_sense_sim.fidelity.food import food_trials
from ext_sense_sim.fidelity.taps import tap_windows
from ext_sense_sim.scene import Scene

__all__ = [
    "FitStep",
    "FreeParameter",
    "StageResult",
    "Target",
    "calibrate_scene",
    "effect_lines",
    "fit",
    "fit_stage",
    "real_statistics",
    "start_values",
    "with_values",
]

STAGES = ("noise", "taps", "food")
"""The fits a scene can run: ``noise`` and ``taps`` for a NUSkin tap scene (noise first, on
the quiet stretch; then the tap, rod and grasp on the windows), ``food`` for a food scene."""


@dataclass(frozen=True)
class StageResult:
    """What one stage fitted: the values, the targets, and the best and first evaluations."""

    stage: str
    free: tuple[FreeParameter, ...]
    targets: tuple[Target, ...]
    first: FitStep
    best: FitStep
    evaluations: int


def real_statistics(stage: str, sessions: Sequence[Any]) -> dict[str, float]:
    """The pooled real statistics a stage fits to, from fidelity :class:`Session` objects."""
    captures = [cap for session in sessions for cap in session.captures]
    if stage == "noise":
        return real_quiet_stats(captures)
    if stage == "taps":
        return window_medians(tap_windows(captures).stats)
    stats = food_trials(captures).stats
    return {name: float(np.nanmedian(values)) for name, values in stats.items()}


def fit_stage(
    scene: Scene,
    stage: str,
    real: Mapping[str, float],
    trials: int,
    seed: int,
    max_evaluations: int = 60,
    on_step: Callable[[FitStep], None] | None = None,
) -> tuple[Scene, StageResult]:
    """Fit one stage of ``scene`` to the real statistics; returns the fitted scene too."""
    if stage == "noise":
        free, tolerances, measure = NOISE_FREE, NOISE_TOLERANCES, noise_measure(trials, seed)
    elif stage == "taps":
        free, tolerances, measure = TAP_FREE, TAP_TOLERANCES, tap_measure(trials, seed)
    elif stage == "food":
        free, tolerances, measure = FOOD_FREE, FOOD_TOLERANCES, food_measure(trials, seed)
    else:
        raise SceneError(f"Unknown calibration stage {stage!r}; expected one of {STAGES}.")
    targets = tuple(Target(n, float(real[n]), tol, log) for n, (tol, log) in tolerances.items())
    _, history = fit(
        scene, free, targets, measure, max_evaluations=max_evaluations, on_step=on_step
    )
    best = min(history, key=lambda step: step.loss)
    fitted = with_values(scene, free, [best.values[p.name] for p in free])
    return fitted, StageResult(stage, tuple(free), targets, history[0], best, len(history))


def read_sessions(scene: Scene, real: Sequence[str]) -> list[Any]:
    """The real sessions of ``--real`` folders, read for the scene's task (taps: its rod)."""
    if check_kind(scene) is Task.FOOD_IDENTIFICATION:
        return [read_food_session(path) for path in real]
    return [read_tap_session(path, rod_cm(scene)) for path in real]


def calibrate_scene(
    scene: Scene,
    real: Sequence[str],
    stages: Sequence[str] | None = None,
    trials: int | None = None,
    seed: int = 5,
    max_evaluations: int = 60,
    log: Callable[[str], None] = print,
) -> str:
    """Run a scene's calibration stages in order and return the fitted scene as YAML text.

    Args:
        scene: A NUSkin tap or food scene.
        real: Real session folders (as for ``sim fidelity``).
        stages: Stages to run (default: ``noise, taps`` for taps, ``food`` for food).
        trials: Simulated trials per evaluation (default: noise 20, taps 200, food 21).
        seed: Seed of every evaluation.
        max_evaluations: Simulations per stage at most.
        log: Where progress lines go.

    Raises:
        SceneError: An unknown stage, or one that does not fit the scene's task.
        FidelityError: Missing or unreadable real captures.
    """
    food = scene.task is Task.FOOD_IDENTIFICATION
    allowed = ("food",) if food else ("noise", "taps")
    stages = tuple(stages or allowed)
    wrong = [s for s in stages if s not in allowed]
    if wrong:
        raise SceneError(
            f"Scene '{scene.name}' ({scene.task.label}) calibrates the stages {allowed}. "
            f"Got {wrong} instead."
        )
    sessions = read_sessions(scene, real)
    for stage in stages:
        stats = real_statistics(stage, sessions)
        n = trials or {"noise": 20, "taps": 200, "food": 21}[stage]
        log(f"[{stage}] {n} simulated trials a step, seed {seed}; real medians:")
        log("    " + ", ".join(f"{k} {v:.4g}" for k, v in stats.items()))

        def show(step: FitStep) -> None:
            values = ", ".join(f"{k} {v:.4g}" for k, v in step.values.items())
            log(f"  loss {step.loss:8.3f}  {values}")

        scene, result = fit_stage(scene, stage, stats, n, seed, max_evaluations, show)
        log(
            f"[{stage}] loss {result.first.loss:.3f} -> {result.best.loss:.3f} in "
            f"{result.evaluations} simulations"
        )
        for target in result.targets:
            log(
                f"    {target.name:20s} real {target.value:10.4g}  first "
                f"{result.first.stats[target.name]:10.4g}  fitted "
                f"{result.best.stats[target.name]:10.4g}"
            )
    lines = effect_lines(scene)
    log("effects:")
    for line in lines:
        log(line)
    source = yaml.safe_load(scene.path.read_text()) if scene.path else {"name": scene.name}
    header = {k: v for k, v in source.items() if k != "effects"}
    return yaml.safe_dump(header, sort_keys=False) + "effects:\n" + "\n".join(lines) + "\n"
