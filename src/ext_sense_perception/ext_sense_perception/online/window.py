"""Contact windows: the record, how they are cut (from the task profile), binning (no ROS).

NUSkin windows hold signed event counts per taxel and bin (+1 per positive or polarity-0 spike,
-1 per negative); BioTac windows the raw PAC samples. :func:`window_from_recording` cuts one
window offline at a known onset, as the online windowers (:mod:`.windowers`) do.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any, NamedTuple

import numpy as np

from ext_sense_perception.errors import PerceptionError
from ext_sense_perception.profiles import OnsetSource, TaskProfile, profile_for
from ext_sense_runtime.enums import Sensor, Task
from ext_sense_runtime.records import EventBlock
from ext_sense_runtime.stamps import MS

NUSKIN_TAXELS = 80
FOOD_CONTACT_DETECTOR = {"activity_window_ns": 300 * MS, "activity_min_events": 230}
"""NUSkin onset detector for a fork's contact with food: 230 events in 300 ms (2.5x the idle
rate). Soft foods rarely trip it, so ``contact`` is no default anchor (docs/decisions.md).
"""


class ContactWindow(NamedTuple):
    """A segment of sensor signal around one contact (the fields of ``ContactWindow.msg``).

    ``data`` is ``(n_channels, n_samples)``; sample ``k`` starts at
    ``onset_ns - pre_onset_ns + k * sample_period_ns`` (negative ``pre_onset_ns``: the window starts
    after the onset). ``provisional``: an anytime window before the final one; ``truncated``:
    closed early with a zero-padded tail; ``degraded``: missing data, joined mid-stream or holding
    a stuck taxel, as ``degraded_reason`` says.
    """

    task: str
    sensor: str
    onset_ns: int
    pre_onset_ns: int
    post_onset_ns: int
    sample_period_ns: int
    channels: np.ndarray
    data: np.ndarray
    provisional: bool = False
    truncated: bool = False
    degraded: bool = False
    degraded_reason: str = ""

    @property
    def start_ns(self) -> int:
        """Time of the first sample, ns."""
        return self.onset_ns - self.pre_onset_ns


@dataclass(frozen=True)
class WindowConfig:
    """How windows are cut for one task and sensor: the task profile plus the onset detector.

    NUSkin onset: ``activity_min_events`` events from at least ``activity_min_taxels`` taxels within
    ``activity_window_ns`` (one taxel at its ceiling is a fault, not a contact); a taxel at
    ``stuck_rate_hz`` for longer than ``stuck_after_ns`` is masked until it quiets. BioTac onset:
    the PAC deviation from its baseline (time constant ``pac_baseline_tau_ns``) over
    ``pac_energy_window_ns`` beyond ``max(pac_min_rms, pac_threshold_sigma * noise)``.
    ``history_ns`` is extra stream kept for late external onsets.
    """

    profile: TaskProfile
    sensor: Sensor = Sensor.NUSKIN
    activity_window_ns: int = 2 * MS
    activity_min_events: int = 8
    activity_min_taxels: int = 2
    stuck_rate_hz: float = 2000.0
    stuck_after_ns: int = 1000 * MS
    pac_energy_window_ns: int = 5 * MS
    pac_threshold_sigma: float = 6.0
    pac_min_rms: float = 8.0
    pac_baseline_tau_ns: int = 50 * MS
    n_taxels: int = NUSKIN_TAXELS
    history_ns: int = 100 * MS

    def __post_init__(self) -> None:
        if not isinstance(self.profile, TaskProfile):
            raise PerceptionError(
                f"The 'profile' parameter must be a TaskProfile. Got {self.profile!r} instead."
            )
        object.__setattr__(self, "sensor", Sensor.parse(self.sensor, PerceptionError))
        _check(self.activity_window_ns > 0, "activity_window_ns", "> 0", self.activity_window_ns)
        _check(
            self.activity_min_events >= 1, "activity_min_events", ">= 1", self.activity_min_events
        )
        _check(
            1 <= self.activity_min_taxels <= self.n_taxels,
            "activity_min_taxels",
            "in [1, n_taxels]",
            self.activity_min_taxels,
        )
        _check(self.stuck_rate_hz > 0, "stuck_rate_hz", "> 0", self.stuck_rate_hz)
        _check(self.stuck_after_ns > 0, "stuck_after_ns", "> 0", self.stuck_after_ns)
        _check(
            self.pac_energy_window_ns > 0, "pac_energy_window_ns", "> 0", self.pac_energy_window_ns
        )
        _check(self.pac_threshold_sigma > 0, "pac_threshold_sigma", "> 0", self.pac_threshold_sigma)
        _check(self.pac_min_rms >= 0, "pac_min_rms", ">= 0", self.pac_min_rms)
        _check(self.pac_baseline_tau_ns > 0, "pac_baseline_tau_ns", "> 0", self.pac_baseline_tau_ns)
        _check(1 <= self.n_taxels <= 65535, "n_taxels", "in [1, 65535]", self.n_taxels)
        _check(self.history_ns >= 0, "history_ns", ">= 0", self.history_ns)

    @classmethod
    def for_task(
        cls, task: str | Task, sensor: str | Sensor, **profile_changes: Any
    ) -> WindowConfig:
        """The task's profile for a sensor with ``profile_changes`` (PerceptionError: a bad one)."""
        profile = profile_for(task)
        if profile_changes:
            try:
                profile = replace(profile, **profile_changes)
            except TypeError as err:
                raise PerceptionError(f"Unknown task profile field: {err}") from err
        return cls(profile, Sensor.parse(sensor, PerceptionError))

    @classmethod
    def for_profile(cls, profile: TaskProfile, sensor: str | Sensor) -> WindowConfig:
        """The configuration that cuts ``profile``'s windows, with the detector it needs.

        A contact-anchored food profile gets :data:`FOOD_CONTACT_DETECTOR`, live and offline alike.
        """
        food_contact = (
            profile.task is Task.FOOD_IDENTIFICATION and profile.onset_source is OnsetSource.SIGNAL
        )
        detector = FOOD_CONTACT_DETECTOR if food_contact else {}
        return cls(profile, Sensor.parse(sensor, PerceptionError), **detector)

    def with_profile(self, **changes: Any) -> WindowConfig:
        """The same configuration with profile fields changed."""
        return replace(self, profile=replace(self.profile, **changes))

    @property
    def task(self) -> Task:
        """The task the windows are for."""
        return self.profile.task

    @property
    def pre_ns(self) -> int:
        """Signal kept before the onset, ns (negative: the window starts after it)."""
        return self.profile.pre_ns

    @property
    def post_ns(self) -> int:
        """Signal after the onset in the final window, ns."""
        return self.profile.post_ns

    @property
    def anytime_post_ns(self) -> tuple[int, ...]:
        """Post-onset times of the provisional (anytime) windows, ns."""
        return self.profile.anytime_post_ns

    @property
    def debounce_ns(self) -> int:
        """Minimum time from one onset to the next, ns."""
        return self.profile.debounce_ns

    @property
    def external_onsets(self) -> bool:
        """Whether onsets come from outside (:meth:`mark_onset` only) rather than the signal."""
        return self.profile.onset_source is OnsetSource.EXTERNAL

    @property
    def period_ns(self) -> int:
        """Sample period of the window data, ns."""
        return self.profile.period_ns(self.sensor)

    def n_samples(self, post_ns: int | None = None) -> int:
        """Samples of a window holding ``post_ns`` after the onset (default: the final one)."""
        post = self.post_ns if post_ns is None else int(post_ns)
        return max(int((self.pre_ns + post) // self.period_ns), 0)


def _check(ok: bool, name: str, expected: str, got: object) -> None:
    if not ok:
        raise PerceptionError(f"The {name!r} parameter must be {expected}. Got {got!r} instead.")


def bin_events(
    events: EventBlock, start_ns: int, n_bins: int, bin_ns: int, n_taxels: int = NUSKIN_TAXELS
) -> np.ndarray:
    """Signed event counts per taxel and bin, ``(n_taxels, n_bins)`` float32.

    Taxel ids outside 1..n_taxels are ignored; polarity 0 counts +1.
    """
    rel = events.t_ns.astype(np.int64, copy=False) - np.int64(start_ns)
    idx = np.floor_divide(rel, np.int64(bin_ns))
    tax = events.taxel.astype(np.int64) - 1
    keep = (rel >= 0) & (idx < n_bins) & (tax >= 0) & (tax < n_taxels)
    flat = tax * n_bins + idx
    size = n_taxels * n_bins
    # integer counts of each sign: the same sums as float +-1 weights (exact in either), about
    # twice as fast on a tap window (the window node cuts one as a packet closes it)
    negative = events.polarity < 0
    counts = np.bincount(flat[keep & ~negative], minlength=size)
    counts -= np.bincount(flat[keep & negative], minlength=size)
    return counts.reshape(n_taxels, n_bins).astype(np.float32)


def window_from_recording(
    config: WindowConfig,
    onset_ns: int,
    *,
    events: EventBlock | None = None,
    pac: np.ndarray | None = None,
    pac_t0_ns: int = 0,
) -> ContactWindow:
    """Cut one final window offline from a whole recording at a known onset, as the windowers do.

    NUSkin needs ``events``; BioTac ``pac`` ``(n_sensors, n_samples)`` from ``pac_t0_ns``
    (PerceptionError: the sensor's arrays missing).
    """
    period = config.period_ns
    n = config.n_samples()
    start = int(onset_ns) - config.pre_ns
    if config.sensor is Sensor.NUSKIN:
        if events is None:
            raise PerceptionError(
                "The 'events' parameter is needed for a NUSkin window. Got None instead."
            )
        data = bin_events(events, start, n, period, config.n_taxels)
        channels = np.arange(1, config.n_taxels + 1, dtype=np.uint16)
    else:
        if pac is None:
            raise PerceptionError(
                "The 'pac' parameter is needed for a BioTac window. Got None instead."
            )
        x = np.atleast_2d(np.asarray(pac, dtype=np.float32))
        first = -(-(start - int(pac_t0_ns)) // period)
        data = np.zeros((x.shape[0], n), np.float32)
        lo, hi = max(first, 0), min(first + n, x.shape[1])
        if lo < hi:
            data[:, lo - first : hi - first] = x[:, lo:hi]
        channels = np.arange(x.shape[0], dtype=np.uint16)
    return ContactWindow(
        task=config.task.label,
        sensor=config.sensor.label,
        onset_ns=int(onset_ns),
        pre_onset_ns=int(config.pre_ns),
        post_onset_ns=int(config.post_ns),
        sample_period_ns=int(period),
        channels=channels,
        data=data,
        provisional=False,
        truncated=False,
    )
