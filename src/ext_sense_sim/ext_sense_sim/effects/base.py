"""What every effect shares: declared inputs and outputs, parameters and per-trial draws.

Effects read named signals from a :class:`Signals` board and write what they give; every signal
carries a leading batch axis (one row per trial).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np

from ext_sense_sim.errors import SceneError


@dataclass(frozen=True)
class TimeBase:
    """The sample grid shared by the effects of one batch (``first_trial``: its run index)."""

    rate_hz: float
    n_samples: int
    n_trials: int
    first_trial: int = 0

    @property
    def dt(self) -> float:
        """Sample period, seconds."""
        return 1.0 / self.rate_hz

    def t(self) -> np.ndarray:
        """Sample times from the trial origin, seconds, shape ``(n_samples,)``."""
        return np.arange(self.n_samples) / self.rate_hz

    def t_ns(self, index: np.ndarray) -> np.ndarray:
        """Integer nanoseconds of sample indices (rounded to the nearest ns)."""
        return np.round(np.asarray(index, dtype=np.float64) * (1e9 / self.rate_hz)).astype(np.int64)


class Signals(dict):
    """The board effects read from and write to, keyed by signal name."""

    def need(self, key: str, effect: str) -> Any:
        """The signal ``key`` for ``effect``, or a :class:`SceneError` naming both."""
        try:
            return self[key]
        except KeyError:
            raise SceneError(
                f"Effect '{effect}' needs the signal '{key}', which no earlier effect gave."
            ) from None


Range = tuple[float, float]


class Effect:
    """Base of all effects, built from the scene's ``params`` and the scene as ``context``.

    Subclasses set ``name``, ``needs``, ``gives``, ``defaults`` (parameter name to default; a
    two-element list is a uniform per-trial range) and implement :meth:`run`.
    """

    name: ClassVar[str] = ""
    needs: ClassVar[tuple[str, ...]] = ()
    gives: ClassVar[tuple[str, ...]] = ()
    defaults: ClassVar[Mapping[str, Any]] = {}

    def __init__(self, params: Mapping[str, Any] | None = None, context: Any = None) -> None:
        params = dict(params or {})
        unknown = sorted(set(params) - set(self.defaults))
        if unknown:
            raise SceneError(
                f"Effect '{self.name}': unknown parameter(s) {unknown}; "
                f"expected some of {sorted(self.defaults)}."
            )
        self.params: dict[str, Any] = {**self.defaults, **params}
        self.context = context
        self.setup()

    def setup(self) -> None:
        """Precompute what does not change between batches (override when useful)."""

    def run(self, signals: Signals, time: TimeBase, rng: np.random.Generator) -> None:
        """Read ``needs`` from ``signals``, write ``gives``."""
        raise NotImplementedError

    # parameter helpers -------------------------------------------------------------------
    def scalar(self, key: str, low: float | None = None, high: float | None = None) -> float:
        """A fixed parameter as float, checked against ``[low, high]``."""
        value = self.params[key]
        try:
            x = float(value)
        except (TypeError, ValueError) as err:
            raise SceneError(
                f"Effect '{self.name}': parameter '{key}' must be a number. Got {value!r} instead."
            ) from err
        _check_bounds(self.name, key, x, low, high)
        return x

    def flag(self, key: str) -> bool:
        """A boolean parameter (``true`` / ``false`` in a scene), checked."""
        value = self.params[key]
        if not isinstance(value, bool):
            raise SceneError(
                f"Effect '{self.name}': parameter '{key}' must be true or false. "
                f"Got {value!r} instead."
            )
        return value

    def draw(
        self,
        key: str,
        rng: np.random.Generator,
        n: int,
        low: float | None = None,
        high: float | None = None,
    ) -> np.ndarray:
        """Per-trial values ``(n,)`` of ``key``: uniform over a range, else constant."""
        value = self.params[key]
        if isinstance(value, (list, tuple)):
            if len(value) != 2:
                raise SceneError(
                    f"Effect '{self.name}': parameter '{key}' must be a number or a [low, high] "
                    f"range. Got {value!r} instead."
                )
            lo, hi = float(value[0]), float(value[1])
            if hi < lo:
                raise SceneError(
                    f"Effect '{self.name}': range '{key}' must have low <= high. Got {value!r}."
                )
            _check_bounds(self.name, key, lo, low, high)
            _check_bounds(self.name, key, hi, low, high)
            return rng.uniform(lo, hi, size=n)
        return np.full(n, self.scalar(key, low, high))


def _check_bounds(effect: str, key: str, x: float, low: float | None, high: float | None) -> None:
    if not np.isfinite(x) or (low is not None and x < low) or (high is not None and x > high):
        raise SceneError(
            f"Effect '{effect}': parameter '{key}' must be finite and in "
            f"[{low}, {high}]. Got {x!r} instead."
        )
