"""The window node's core, with no rclpy import: sensor messages in, contact windows out.

The node only moves messages; everything it decides happens here, so that the offline replay
(``ext-sense replay --offline``), training from bags and device streams drive the very same code
and two runs on one bag give identical windows. Messages are duck-typed: rclpy messages and
rosbags messages have the same field names.
"""

from __future__ import annotations

from collections import OrderedDict
from typing import Any, NamedTuple

import numpy as np

from ext_sense_perception.errors import PerceptionError
from ext_sense_perception.online.pac_windower import PacWindower
from ext_sense_perception.online.window import ContactWindow, WindowConfig
from ext_sense_perception.online.windowers import EventWindower
from ext_sense_runtime.enums import Sensor
from ext_sense_runtime.records import EventBlock
from ext_sense_runtime.stamps import stamp_to_ns

JOIN_DEPTH = 64
"""BioTac frames of several sensors waiting for their siblings (same sequence) at most."""


def make_windower(config: WindowConfig, n_sensors: int = 1) -> EventWindower | PacWindower:
    """The windower for the config's sensor (``n_sensors`` BioTac PAC channels; NUSkin: unused)."""
    if config.sensor is Sensor.NUSKIN:
        return EventWindower(config)
    return PacWindower(config, n_sensors=n_sensors)


class StageCounters(NamedTuple):
    """What a :class:`WindowStage` dropped or joined (monotonic)."""

    batches: int = 0
    events: int = 0
    frames: int = 0
    frames_unjoined: int = 0
    frames_wrong_sensor: int = 0
    bad_messages: int = 0


class WindowStage:
    """Sensor messages in, contact windows out.

    Args:
        config: Window configuration (task, sensor, durations).
        sensor_ids: BioTac sensor slots to join into one multi-channel window (NUSkin: unused).

    Raises:
        PerceptionError: An empty ``sensor_ids`` for BioTac.
    """

    def __init__(self, config: WindowConfig, sensor_ids: tuple[int, ...] = (0,)) -> None:
        self.config = config
        self.sensor_ids = tuple(int(s) for s in sensor_ids)
        if config.sensor is Sensor.BIOTAC and not self.sensor_ids:
            raise PerceptionError("The 'sensor_ids' parameter must name at least one sensor.")
        self.windower = make_windower(config, n_sensors=max(1, len(self.sensor_ids)))
        self._counts = dict.fromkeys(StageCounters._fields, 0)
        self._join: OrderedDict[int, dict[int, Any]] = OrderedDict()
        self.last_data_ns: int | None = None
        """Stream time of the newest data fed, ns (None before any)."""

    @property
    def counters(self) -> StageCounters:
        """Counters since construction."""
        return StageCounters(**self._counts)

    def on_events(self, msg: Any) -> list[ContactWindow]:
        """Feed one ``TaxelEventBatch``; returns the windows that became due.

        A malformed batch (arrays of different lengths, negative offsets) is counted in
        ``bad_messages`` and dropped whole.
        """
        self._counts["batches"] += 1
        events = events_of(msg)
        if events is None:
            self._counts["bad_messages"] += 1
            return []
        return self.on_block(events, stamp_to_ns(msg.header.stamp))

    def on_block(self, events: EventBlock, stamp_ns: int | None = None) -> list[ContactWindow]:
        """Feed a block of decoded events (a driver's, the simulator's); windows that became due.

        ``stamp_ns`` is the batch's stamp (the start of the time it covers): with no events,
        stream time still reaches it, so an empty batch past a window's end closes the window
        on data, as an event there would (the stream is in order: nothing earlier can follow).
        """
        self._counts["events"] += events.size
        end = int(events.t_ns.max()) if events.size else stamp_ns
        if end is not None:
            self.last_data_ns = end if self.last_data_ns is None else max(self.last_data_ns, end)
        return self.windower.feed(events, now_ns=None if events.size else stamp_ns)

    def on_frame(self, msg: Any) -> list[ContactWindow]:
        """Feed one ``BioTacFrame``; frames of several sensors are joined by sequence number.

        Frames of sensors not in ``sensor_ids`` are counted and dropped; a sequence whose
        sibling frames never arrive is dropped (counted) once ``JOIN_DEPTH`` newer ones wait.
        """
        self._counts["frames"] += 1
        sid = int(msg.sensor_id)
        if sid not in self.sensor_ids:
            self._counts["frames_wrong_sensor"] += 1
            return []
        seq = int(msg.sequence)
        group = self._join.setdefault(seq, {})
        group[sid] = msg
        if len(group) < len(self.sensor_ids):
            while len(self._join) > JOIN_DEPTH:
                _, dropped = self._join.popitem(last=False)
                self._counts["frames_unjoined"] += len(dropped)
            return []
        del self._join[seq]
        frames = [group[s] for s in self.sensor_ids]
        pac = np.stack([np.asarray(f.pac, dtype=np.float64) for f in frames])
        valid = np.ones_like(pac, dtype=bool)
        for row, frame in enumerate(frames):
            mask = int(frame.invalid_word_mask)
            if mask:
                shifts = 2 * np.arange(pac.shape[1], dtype=np.uint64)  # PAC words are even
                valid[row] = ((np.uint64(mask) >> shifts) & np.uint64(1)) == 0
        t0 = stamp_to_ns(frames[0].header.stamp)
        period = int(frames[0].pac_sample_period_ns)
        try:
            out = self.windower.feed(t0, pac, period, valid=valid)
        except PerceptionError:
            self._counts["bad_messages"] += 1
            return []
        end = t0 + period * pac.shape[1]
        self.last_data_ns = end if self.last_data_ns is None else max(self.last_data_ns, end)
        return out

    def on_motion_start(self, onset_ns: int) -> bool:
        """Mark an onset known from outside (food: the arm starts moving); False if debounced."""
        return self.windower.mark_onset(int(onset_ns))

    def advance(self, now_ns: int) -> list[ContactWindow]:
        """Declare the stream complete up to ``now_ns`` (no more data before it will come)."""
        return self.windower.advance(int(now_ns))

    def next_due_ns(self) -> int | None:
        """Stream time at which the next pending window becomes due, ns (None: none pending)."""
        return self.windower.next_due_ns

    def flush(self) -> list[ContactWindow]:
        """Close every pending window (the stream stopped); tails are zero-padded."""
        return self.windower.flush()


def events_of(msg: Any) -> EventBlock | None:
    """The events of a ``TaxelEventBatch``, or None when the batch is malformed.

    Malformed: the arrays differ in length (an empty ``value`` stands for all zeros) or an
    offset is negative.
    """
    offset = np.asarray(msg.offset_ns, dtype=np.int64)
    taxel = np.asarray(msg.taxel, dtype=np.uint16)
    polarity = np.asarray(msg.polarity, dtype=np.int8)
    value = np.asarray(msg.value, dtype=np.uint16)
    n = len(offset)
    if not len(value):
        value = np.zeros(n, np.uint16)
    if not (n == len(taxel) == len(polarity) == len(value)) or (n and int(offset.min()) < 0):
        return None
    return EventBlock(offset + np.int64(stamp_to_ns(msg.header.stamp)), taxel, polarity, value)
