"""Task profiles: how each task's contact windows are cut and read, defined once (no ROS).

The window node, the inference node, the CLI, the demo and the report all read the profile a
model was trained with, so the live graph and the model cannot disagree on the window.
``sample_ns`` is a NUSkin window's bin of signed counts (BioTac windows hold PAC samples);
``feature_bin_ns`` the coarser bin the FFT / baseline features rebin it to.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, replace
from enum import Enum
from typing import Any

from ext_sense_perception.errors import PerceptionError
from ext_sense_runtime.enums import Sensor, Task
from ext_sense_runtime.stamps import MS

PAC_PERIOD_NS = 454_545
"""BioTac PAC sample period (2200 Hz), ns."""


class OnsetSource(str, Enum):
    """Where a window's onset comes from."""

    SIGNAL = "signal"
    """Detected causally from the sensor stream (tap, handover)."""
    EXTERNAL = "external"
    """Given from outside: the start of the arm's motion (food)."""


@dataclass(frozen=True)
class TaskProfile:
    """How one task's windows are cut and read.

    Attributes:
        pre_ns: Signal kept before the onset, ns (negative: the window starts after it).
        post_ns: Signal after the onset in the final window, ns.
        sample_ns: NUSkin window sample period (bin of signed counts), ns.
        anytime_post_ns: Shorter post-onset times of provisional windows and anytime models, ns,
            ascending, each in ``(-pre_ns, post_ns)``.
        feature_bin_ns: NUSkin FFT / baseline feature bin, ns (a multiple of ``sample_ns``).
        onset_source: Where the onset comes from.
        debounce_ns: Minimum time from one onset to the next, ns.
    """

    task: Task
    pre_ns: int
    post_ns: int
    sample_ns: int
    anytime_post_ns: tuple[int, ...]
    feature_bin_ns: int
    onset_source: OnsetSource
    debounce_ns: int

    def __post_init__(self) -> None:
        object.__setattr__(self, "task", Task.parse(self.task, PerceptionError))
        object.__setattr__(self, "onset_source", _onset_source(self.onset_source))
        object.__setattr__(
            self, "anytime_post_ns", tuple(sorted(int(p) for p in self.anytime_post_ns))
        )
        for name in ("pre_ns", "post_ns", "sample_ns", "feature_bin_ns", "debounce_ns"):
            object.__setattr__(self, name, int(getattr(self, name)))
        _check(0 < self.post_ns <= 60_000 * MS, "post_ns", "in (0, 60 s]", self.post_ns)
        _check(-self.pre_ns < self.post_ns, "pre_ns", f"> -post_ns ({-self.post_ns})", self.pre_ns)
        _check(self.pre_ns <= 10_000 * MS, "pre_ns", "<= 10 s", self.pre_ns)
        _check(0 < self.sample_ns <= 1000 * MS, "sample_ns", "in (0, 1 s]", self.sample_ns)
        _check(
            self.feature_bin_ns > 0 and self.feature_bin_ns % self.sample_ns == 0,
            "feature_bin_ns",
            f"a positive multiple of sample_ns ({self.sample_ns})",
            self.feature_bin_ns,
        )
        for p in self.anytime_post_ns:
            _check(
                -self.pre_ns < p < self.post_ns,
                "anytime_post_ns",
                f"each in ({-self.pre_ns}, {self.post_ns})",
                p,
            )
        _check(self.debounce_ns >= 0, "debounce_ns", ">= 0", self.debounce_ns)

    def period_ns(self, sensor: Sensor | str) -> int:
        """Sample period of this task's windows from a sensor, ns."""
        is_nuskin = Sensor.parse(sensor, PerceptionError) is Sensor.NUSKIN
        return self.sample_ns if is_nuskin else PAC_PERIOD_NS

    def with_window(self, pre_ns: int, post_ns: int) -> TaskProfile:
        """The same profile for another window; anytime times that no longer fit are dropped.

        For recordings that cannot hold the task's window (the real food captures); the card records
        the window used.
        """
        posts = tuple(p for p in self.anytime_post_ns if -pre_ns < p < post_ns)
        return replace(self, pre_ns=int(pre_ns), post_ns=int(post_ns), anytime_post_ns=posts)

    def study_post_ns(self) -> tuple[int, ...]:
        """Post-contact times of a latency study: the anytime ones (else thirds), then the final."""
        if self.anytime_post_ns:
            return (*self.anytime_post_ns, self.post_ns)
        start = max(-self.pre_ns, 0)
        step = (self.post_ns - start) // 3
        return (start + step, start + 2 * step, self.post_ns)

    def to_dict(self) -> dict[str, Any]:
        """The profile as JSON-ready values (model cards)."""
        out = asdict(self)
        out["task"] = self.task.label
        out["onset_source"] = self.onset_source.value
        out["anytime_post_ns"] = list(self.anytime_post_ns)
        return out

    @classmethod
    def from_dict(cls, values: dict[str, Any]) -> TaskProfile:
        """A profile from :meth:`to_dict` values (PerceptionError: bad or missing fields)."""
        names = {f for f in cls.__dataclass_fields__}
        if not isinstance(values, dict) or set(values) != names:
            got = sorted(values) if isinstance(values, dict) else type(values).__name__
            raise PerceptionError(
                f"The 'profile' must have exactly the fields {sorted(names)}. Got {got} instead."
            )
        try:
            return cls(**values)
        except (TypeError, ValueError) as err:
            raise PerceptionError(f"The 'profile' is invalid: {err}") from err


def _onset_source(value: object) -> OnsetSource:
    try:
        return OnsetSource(value)
    except ValueError as err:
        raise PerceptionError(
            f"The 'onset_source' parameter must be 'signal' or 'external'. Got {value!r} instead."
        ) from err


def _check(ok: bool, name: str, expected: str, got: object) -> None:
    if not ok:
        raise PerceptionError(f"The {name!r} parameter must be {expected}. Got {got!r} instead.")


_TAP_HANDOVER_ANYTIME = (25 * MS, 50 * MS, 100 * MS, 150 * MS)

PROFILES: dict[Task, TaskProfile] = {
    # the paper's window: 50 ms before to 250 ms after the contact; FFT on 5 ms bins
    Task.TAP_LOCALIZATION: TaskProfile(
        task=Task.TAP_LOCALIZATION,
        pre_ns=50 * MS,
        post_ns=250 * MS,
        sample_ns=1 * MS,
        anytime_post_ns=_TAP_HANDOVER_ANYTIME,
        feature_bin_ns=5 * MS,
        onset_source=OnsetSource.SIGNAL,
        debounce_ns=500 * MS,
    ),
    # the tap window; 2 ms feature bins (simulated rod handovers: 0.75 accuracy with FFT + SVM
    # against chance with the paper's 5 ms bins)
    Task.HANDOVER_STABILITY: TaskProfile(
        task=Task.HANDOVER_STABILITY,
        pre_ns=50 * MS,
        post_ns=250 * MS,
        sample_ns=1 * MS,
        anytime_post_ns=_TAP_HANDOVER_ANYTIME,
        feature_bin_ns=2 * MS,
        onset_source=OnsetSource.SIGNAL,
        debounce_ns=500 * MS,
    ),
    # the paper's food window: 2 s to 8 s after the arm starts moving; 10 ms samples (the real
    # captures' timestamps have 10 ms resolution), 50 ms feature bins; no anytime models
    Task.FOOD_IDENTIFICATION: TaskProfile(
        task=Task.FOOD_IDENTIFICATION,
        pre_ns=-2000 * MS,
        post_ns=8000 * MS,
        sample_ns=10 * MS,
        anytime_post_ns=(),
        feature_bin_ns=50 * MS,
        onset_source=OnsetSource.EXTERNAL,
        debounce_ns=8000 * MS,
    ),
}

FOOD_CAPTURE_POST_NS = 3000 * MS
"""The real food captures end about 3.1 s after the arm starts moving: their window is 0-3 s."""


class Anchor(str, Enum):
    """What a food window's onset is tied to when windows are cut from recordings (on the card).

    Live, ``arm_motion`` and ``capture_start`` windows are cut at the food behaviour's motion mark,
    ``contact`` windows at the onset the window node detects.
    """

    ARM_MOTION = "arm_motion"
    """The start of the arm's motion (from the arm's joint velocities)."""
    CAPTURE_START = "capture_start"
    """The start of the capture (its first line); the arm moves ``CAPTURE_LEAD_NS`` later."""
    CONTACT = "contact"
    """The fork's tactile onset, detected by the live windower's detector."""

    @classmethod
    def parse(cls, value: object) -> Anchor:
        """The anchor named ``value`` (a PerceptionError for an unknown name)."""
        try:
            return cls(value)
        except ValueError as err:
            names = ", ".join(a.value for a in cls)
            raise PerceptionError(
                f"The 'anchor' parameter must be one of {names}. Got {value!r} instead."
            ) from err


CAPTURE_LEAD_NS = 580 * MS
"""From a food capture's start to the arm's motion start (median of the 1 April 2021 trials
with arm bags, 0.54-0.60 s), so ``capture_start`` windows are served from the motion mark.
"""
CAPTURE_POST_NS = 2920 * MS
"""Post-onset span of ``capture_start`` windows: the window covers the capture's first 3.5 s."""
CONTACT_PRE_NS = 500 * MS
"""Signal kept before a detected food contact, ns."""
CONTACT_POST_NS = 2000 * MS
"""Signal after a detected food contact, ns."""


def capture_profile(anchor: Anchor | str) -> TaskProfile:
    """The food profile for windows cut from real captures at ``anchor``.

    ``arm_motion``: 0 to 3 s after the motion start; ``capture_start``: the capture's first 3.5 s
    (external onset); ``contact``: around the detected contact (onset from the signal).
    """
    food = PROFILES[Task.FOOD_IDENTIFICATION]
    anchor = Anchor.parse(anchor)
    if anchor is Anchor.ARM_MOTION:
        return food.with_window(0, FOOD_CAPTURE_POST_NS)
    if anchor is Anchor.CAPTURE_START:
        return food.with_window(CAPTURE_LEAD_NS, CAPTURE_POST_NS)
    return replace(
        food.with_window(CONTACT_PRE_NS, CONTACT_POST_NS), onset_source=OnsetSource.SIGNAL
    )


def profile_for(task: Task | str) -> TaskProfile:
    """The task's profile (a PerceptionError for an unknown task)."""
    return PROFILES[Task.parse(task, PerceptionError)]
