"""Fitting a scene's physics to real captures (``ext-sense sim calibrate``).

:mod:`.search` holds the deterministic coordinate search over a scene's free parameters,
:mod:`.stages` what each stage fits and how it measures a scene; :func:`calibrate_scene` runs a
scene's stages against real sessions (docs/simulator.md, "Calibration against the real sensor").
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import yaml

from ext_sense_runtime.enums import Task
from ext_sense_sim.calibration.search import FitStep, Target, effect_lines, fit, with_values
from ext_sense_sim.calibration.stages import STAGES
from ext_sense_sim.errors import SceneError
from ext_sense_sim.fidelity.captures import read_sessions
from ext_sense_sim.scene import Scene


def calibrate_scene(
    scene: Scene,
    real: Sequence[str],
    stages: Sequence[str] | None = None,
    trials: int | None = None,
    seed: int = 5,
    max_evaluations: int = 60,
    log: Callable[[str], None] = print,
    hold: Sequence[str] = (),
) -> str:
    """Run a NUSkin tap or food scene's calibration stages and return the fitted scene's YAML.

    ``real`` are session folders as for ``sim fidelity``; ``stages`` default to ``noise, taps``
    for taps, ``food`` for food; every evaluation simulates ``trials`` (default: the stage's)
    with ``seed``, at most ``max_evaluations`` per stage. ``hold`` names free parameters
    (``effect.key``) kept at the scene's value: a sensor property fitted on another scene.

    Raises:
        SceneError: An unknown stage, one that does not fit the scene's task, or a held
            parameter that none of the stages frees.
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
    freed = {p.name for name in stages for p in STAGES[name].free}
    unknown = sorted(set(hold) - freed)
    if unknown:
        raise SceneError(f"Cannot hold {unknown}: the stages {stages} free only {sorted(freed)}.")
    captures = [cap for session in read_sessions(scene, real) for cap in session.captures]
    for name in stages:
        stage = STAGES[name]
        free = tuple(p for p in stage.free if p.name not in hold)
        stats = stage.real(captures)
        n = trials or stage.trials
        log(f"[{name}] {n} simulated trials a step, seed {seed}; real medians:")
        log("    " + ", ".join(f"{k} {v:.4g}" for k, v in stats.items()))

        def show(step: FitStep) -> None:
            values = ", ".join(f"{k} {v:.4g}" for k, v in step.values.items())
            log(f"  loss {step.loss:8.3f}  {values}")

        targets = [
            Target(k, float(stats[k]), t, as_log) for k, (t, as_log) in stage.tolerances.items()
        ]
        values, history = fit(
            scene,
            free,
            targets,
            stage.measure(n, seed, captures),
            max_evaluations=max_evaluations,
            on_step=show,
        )
        scene = with_values(scene, free, values)
        first, best = history[0], min(history, key=lambda step: step.loss)
        log(f"[{name}] loss {first.loss:.3f} -> {best.loss:.3f} in {len(history)} simulations")
        for target in targets:
            log(
                f"    {target.name:20s} real {target.value:10.4g}  first "
                f"{first.stats[target.name]:10.4g}  fitted {best.stats[target.name]:10.4g}"
            )
    lines = effect_lines(scene)
    log("effects:")
    for line in lines:
        log(line)
    source = yaml.safe_load(scene.path.read_text()) if scene.path else {"name": scene.name}
    header = {k: v for k, v in source.items() if k != "effects"}
    return yaml.safe_dump(header, sort_keys=False) + "effects:\n" + "\n".join(lines) + "\n"
