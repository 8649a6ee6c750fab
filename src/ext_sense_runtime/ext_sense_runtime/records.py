"""The records every ext_sense package passes around: one type per idea (no rclpy).

:class:`EventBlock` (NUSkin events), :class:`GroundTruth` (one trial), :class:`Estimate` (one
window's conclusion); :func:`estimate_of` and :func:`truth_of` read the messages (rclpy or
rosbags: the same field names).
"""

from __future__ import annotations

import math
from typing import Any, NamedTuple

import numpy as np
import numpy.typing as npt

from ext_sense_runtime.stamps import stamp_to_ns


class EventBlock(NamedTuple):
    """NUSkin events, parallel arrays with one entry per event.

    Attributes:
        t_ns: Time of each event, integer ns, shape ``(n,)`` int64.
        taxel: Taxel id 1..80 (1..40 left finger, 41..80 right), shape ``(n,)`` uint16.
        polarity: +1 positive spike, -1 negative, 0 unknown, shape ``(n,)`` int8.
        value: The receiver's 10-bit value field (0 when the source has none), ``(n,)`` uint16.
    """

    t_ns: npt.NDArray[np.int64]
    taxel: npt.NDArray[np.uint16]
    polarity: npt.NDArray[np.int8]
    value: npt.NDArray[np.uint16]

    @property
    def size(self) -> int:
        """Number of events (``len()`` of a NamedTuple is its field count, so not that)."""
        return int(self.t_ns.shape[0])

    @classmethod
    def empty(cls) -> EventBlock:
        """A block with no events."""
        return cls.of(np.empty(0, np.int64), np.empty(0, np.uint16))

    @classmethod
    def of(
        cls,
        t_ns: npt.ArrayLike,
        taxel: npt.ArrayLike,
        polarity: npt.ArrayLike | None = None,
        value: npt.ArrayLike | None = None,
    ) -> EventBlock:
        """A block from loose arrays in the record's dtypes (polarity and value default to 0).

        Raises:
            ValueError: The arrays are not 1-D of one length, or the times are not integers.
        """
        t = np.asarray(t_ns)
        if t.dtype.kind not in "iu":
            raise ValueError(
                f"The 't_ns' parameter must be integer nanoseconds. Got dtype {t.dtype} instead."
            )
        n = t.shape[0] if t.ndim == 1 else -1
        tax = np.asarray(taxel)
        pol = np.zeros(max(n, 0), np.int8) if polarity is None else np.asarray(polarity)
        val = np.zeros(max(n, 0), np.uint16) if value is None else np.asarray(value)
        if n < 0 or any(a.shape != (n,) for a in (tax, pol, val)):
            raise ValueError(
                "The 't_ns', 'taxel', 'polarity' and 'value' parameters must be 1-D of one "
                f"length. Got shapes {t.shape}, {tax.shape}, {pol.shape}, {val.shape} instead."
            )
        return cls(
            t.astype(np.int64, copy=False),
            tax.astype(np.uint16, copy=False),
            pol.astype(np.int8, copy=False),
            val.astype(np.uint16, copy=False),
        )

    @classmethod
    def concat(cls, blocks: list[EventBlock]) -> EventBlock:
        """Join blocks end to end (an empty list gives an empty block)."""
        if not blocks:
            return cls.empty()
        return cls(*(np.concatenate([b[i] for b in blocks]) for i in range(4)))

    def select(self, mask: npt.ArrayLike) -> EventBlock:
        """The events where ``mask`` (boolean or index array) selects."""
        return EventBlock(*(a[mask] for a in self))

    def sorted_by_time(self) -> EventBlock:
        """The same events in time order (stable: equal times keep their order)."""
        if self.size < 2 or not np.any(np.diff(self.t_ns) < 0):
            return self
        return self.select(np.argsort(self.t_ns, kind="stable"))


class GroundTruth(NamedTuple):
    """What really happened in one trial (the fields of ``ContactGroundTruth``).

    ``onset_ns`` (food: the arm's motion start) is on the clock of the stream it labels; the
    tap position is from the held end, metres; fields that do not apply are NaN or empty.
    """

    trial: int
    onset_ns: int
    task: str = ""
    tap_position_m: float = math.nan
    class_label: str = ""
    rod_length_m: float = math.nan

    @property
    def label(self) -> float | str:
        """The training label: the tap position when there is one, else the class."""
        return self.tap_position_m if math.isfinite(self.tap_position_m) else self.class_label


class Estimate(NamedTuple):
    """What a model concluded about one contact window (fields of ``ContactEstimate``).

    Fields that do not apply are NaN, -1, "" or empty. Times are integer ns (``onset_ns``:
    food's motion start), positions metres from the held end. ``provisional``: an anytime
    estimate from a shortened window; ``degraded``: its window missed data, or it came after
    the inference node's deadline (``degraded_reason`` says which).
    """

    task: str
    onset_ns: int
    sensor: str = ""
    model_id: str = ""
    provisional: bool = False
    post_contact_used_ns: int = 0
    compute_latency_ns: int = 0
    tap_position_m: float = math.nan
    tap_position_std_m: float = math.nan
    class_index: int = -1
    class_label: str = ""
    class_names: tuple[str, ...] = ()
    class_probabilities: tuple[float, ...] = ()
    stability_probability: float = math.nan
    degraded: bool = False
    degraded_reason: str = ""


def estimate_of(msg: Any) -> Estimate:
    """The :class:`Estimate` of a ``ContactEstimate`` message (rclpy or rosbags)."""
    return Estimate(
        task=str(msg.task),
        onset_ns=stamp_to_ns(msg.header.stamp),
        sensor=str(msg.sensor),
        model_id=str(msg.model_id),
        provisional=bool(msg.provisional),
        post_contact_used_ns=stamp_to_ns(msg.post_contact_used),
        compute_latency_ns=stamp_to_ns(msg.compute_latency),
        tap_position_m=float(msg.tap_position_m),
        tap_position_std_m=float(msg.tap_position_std_m),
        class_index=int(msg.class_index),
        class_label=str(msg.class_label),
        class_names=tuple(str(n) for n in msg.class_names),
        class_probabilities=tuple(float(p) for p in msg.class_probabilities),
        stability_probability=float(msg.stability_probability),
        degraded=bool(getattr(msg, "degraded", False)),
        degraded_reason=str(getattr(msg, "degraded_reason", "")),
    )


def truth_of(msg: Any) -> GroundTruth:
    """The :class:`GroundTruth` of a ``ContactGroundTruth`` message (rclpy or rosbags)."""
    return GroundTruth(
        trial=int(msg.trial),
        onset_ns=stamp_to_ns(msg.header.stamp),
        task=str(msg.task),
        tap_position_m=float(msg.tap_position_m),
        class_label=str(msg.class_label),
        rod_length_m=float(msg.rod_length_m),
    )
