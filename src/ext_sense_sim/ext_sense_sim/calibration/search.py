"""Fitting a scene's free physical parameters to statistics of real captures.

:func:`fit` is a deterministic coordinate search in log space: each :class:`FreeParameter` in
turn is multiplied and divided by a step, a change kept when it lowers the loss (the mean squared
miss of each :class:`Target` in tolerance units), the step halved (in log) when a round keeps
nothing. Every evaluation simulates the same trials and seed, so a rerun gives the same fit.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from ext_sense_sim.effects import REGISTRY
from ext_sense_sim.errors import SceneError
from ext_sense_sim.scene import Scene


@dataclass(frozen=True)
class FreeParameter:
    """One parameter of one effect that the fit may move, within ``[low, high]``.

    With ``spread = (a, b)`` the parameter is a range with the centre ``v``: a scalar in the scene
    (or a range from zero) is written ``[a v, b v]``; a range in the scene is scaled to the new
    centre, so its width (fitted by a :class:`FreeWidth` or not) stays. Its centre is
    ``sqrt(lo hi / (a b))``.
    """

    effect: str
    key: str
    low: float
    high: float
    spread: tuple[float, float] | None = None

    @property
    def name(self) -> str:
        """``effect.key``, as printed and documented."""
        return f"{self.effect}.{self.key}"

    def apply(self, params: dict[str, Any], value: float) -> None:
        """Set the parameter in an effect's parameters ``params`` to the fitted ``value``."""
        if self.spread is None:  # a scalar, whatever the scene held
            params[self.key] = float(value)
            return
        current = params.get(self.key)
        centre = self.read(params) if isinstance(current, (list, tuple)) else 0.0
        if centre > 0:
            scale = value / centre
            params[self.key] = _range(float(current[0]) * scale, float(current[1]) * scale)
        else:
            params[self.key] = _range(value * self.spread[0], value * self.spread[1])

    def read(self, params: Mapping[str, Any]) -> float:
        """The fitted value a scene's parameters hold (a range's centre by ``spread``)."""
        value = params[self.key]
        if self.spread is None:
            if isinstance(value, (list, tuple)):
                raise SceneError(
                    f"Parameter '{self.name}' is a range {value!r}: fit it with a spread "
                    "(the ratios of its ends to the fitted centre)."
                )
            return float(value)
        if not isinstance(value, (list, tuple)):
            return float(value)
        return math.sqrt(float(value[0]) * float(value[1]) / (self.spread[0] * self.spread[1]))


@dataclass(frozen=True)
class FreeWidth:
    """How wide a range parameter is, ``r`` in ``[low, high]``: the range ``[g / r, g r]``.

    ``g`` is the range's geometric centre, which the width keeps (and a centre fitted by a
    :class:`FreeParameter` keeps the width), so the two commute. A scalar is a range of width 1.
    """

    effect: str
    key: str
    low: float = 1.0
    high: float = 3.0

    @property
    def name(self) -> str:
        """``effect.key.width``, as printed and documented."""
        return f"{self.effect}.{self.key}.width"

    def apply(self, params: dict[str, Any], value: float) -> None:
        """Set the range's width to ``value``, about its geometric centre."""
        lo, hi = self._ends(params)
        centre = math.sqrt(lo * hi)
        params[self.key] = _range(centre / value, centre * value)

    def read(self, params: Mapping[str, Any]) -> float:
        """The width of the range the parameters hold (1 for a scalar)."""
        lo, hi = self._ends(params)
        return 1.0 if lo == hi else math.sqrt(hi / lo)

    def _ends(self, params: Mapping[str, Any]) -> tuple[float, float]:
        """The range's ends (a scalar's twice); a range that is not positive is refused."""
        value = params[self.key]
        if not isinstance(value, (list, tuple)):
            return float(value), float(value)
        lo, hi = float(value[0]), float(value[1])
        if lo <= 0 or hi < lo:
            raise SceneError(
                f"Parameter '{self.name}' needs a positive range to have a width, got {value!r}."
            )
        return lo, hi


def _range(low: float, high: float) -> list[float]:
    """A range as the scenes write it: both ends to 6 decimals."""
    return [round(low, 6), round(high, 6)]


Free = FreeParameter | FreeWidth
"""A fitted value: a parameter (or a range's centre) or a range's width."""


@dataclass(frozen=True)
class Target:
    """A statistic to match: its real value and the miss counted as one unit of loss.

    ``log`` targets compare ``log(sim / real)`` instead of ``sim - real``.
    """

    name: str
    value: float
    tolerance: float
    log: bool = False

    def miss(self, simulated: float) -> float:
        """The simulated value's miss in tolerance units (signed)."""
        if self.log:
            if simulated <= 0 or self.value <= 0:
                return math.inf
            return math.log(simulated / self.value) / self.tolerance
        return (simulated - self.value) / self.tolerance


Measure = Callable[[Scene], Mapping[str, float]]


@dataclass(frozen=True)
class FitStep:
    """One evaluation of the search: the values tried and the loss they gave."""

    values: dict[str, float]
    loss: float
    stats: dict[str, float]


def with_values(scene: Scene, free: Sequence[Free], values: Sequence[float]) -> Scene:
    """A copy of ``scene`` with each free parameter set to its value."""
    effects = [(name, dict(params)) for name, params in scene.effects]
    for parameter, value in zip(free, values, strict=True):
        params = _params_of(scene, effects, parameter)
        defaults = REGISTRY[parameter.effect].defaults
        if parameter.key not in params and parameter.key in defaults:
            params[parameter.key] = defaults[parameter.key]
        parameter.apply(params, value)
    return dataclasses.replace(scene, effects=tuple(effects))


def _params_of(
    scene: Scene, effects: list[tuple[str, dict[str, Any]]], parameter: Free
) -> dict[str, Any]:
    for name, params in effects:
        if name == parameter.effect:
            return params
    raise SceneError(
        f"Scene '{scene.name}' has no effect '{parameter.effect}' to calibrate "
        f"(parameter '{parameter.name}')."
    )


def start_values(scene: Scene, free: Sequence[Free]) -> list[float]:
    """The free parameters' values in the scene, or their effects' defaults."""
    effects = [(name, dict(params)) for name, params in scene.effects]
    values = []
    for parameter in free:
        given = _params_of(scene, effects, parameter)
        value = parameter.read({**REGISTRY[parameter.effect].defaults, **given})
        values.append(min(max(value, parameter.low), parameter.high))
    return values


def loss(stats: Mapping[str, float], targets: Sequence[Target]) -> float:
    """Mean squared miss of the statistics, in tolerance units."""
    return sum(t.miss(stats[t.name]) ** 2 for t in targets) / len(targets)


def fit(
    scene: Scene,
    free: Sequence[Free],
    targets: Sequence[Target],
    measure: Measure,
    *,
    step: float = 1.6,
    min_step: float = 1.05,
    max_evaluations: int = 80,
    on_step: Callable[[FitStep], None] | None = None,
) -> tuple[list[float], list[FitStep]]:
    """Coordinate search of the free parameters from the scene's values (see module docstring).

    ``measure`` simulates a scene and returns its statistics; the search ends when the step
    falls below ``min_step`` or after ``max_evaluations``. Returns the best values and every
    step in order.
    """
    values = start_values(scene, free)
    history: list[FitStep] = []

    def evaluate(candidate: list[float]) -> float:
        stats = dict(measure(with_values(scene, free, candidate)))
        record = FitStep(
            {p.name: v for p, v in zip(free, candidate, strict=True)}, loss(stats, targets), stats
        )
        history.append(record)
        if on_step is not None:
            on_step(record)
        return record.loss

    best = evaluate(values)
    factor = step
    while factor >= min_step and len(history) < max_evaluations:
        improved = False
        for i, parameter in enumerate(free):
            for direction in (factor, 1.0 / factor):
                if len(history) >= max_evaluations:
                    break
                trial = list(values)
                trial[i] = min(max(values[i] * direction, parameter.low), parameter.high)
                if trial[i] == values[i]:
                    continue
                score = evaluate(trial)
                if score < best:
                    best, values, improved = score, trial, True
                    break
        if not improved:
            factor = math.sqrt(factor)
    return values, history


def effect_lines(scene: Scene) -> list[str]:
    """The scene's ``effects:`` list in the shipped scenes' one-line flow style."""
    lines = []
    for name, params in scene.effects:
        if not params:
            lines.append(f"  - {name}")
            continue
        items = ", ".join(f"{k}: {_flow(v)}" for k, v in params.items())
        lines.append(f"  - {name}: {{{items}}}")
    return lines


def _flow(value: Any) -> str:
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(_flow(v) for v in value) + "]"
    if isinstance(value, float):
        return f"{value:.6g}"
    return str(value).lower() if isinstance(value, bool) else str(value)
