"""Labelled windows from a rosbag2 bag, cut by the live graph's own windowing code (no ROS).

The sensor stream (``SensorPacket``, else the decoded arrays of older bags) goes through
:class:`~ext_sense_perception.online.stage.WindowStage` in log-time order. Onsets are the
``ContactGroundTruth`` stamps (``truth``, debounce off, as ``dataset.npz`` is cut) or detected
as live (``detected``, labelled by the nearest truth). Undecodable and malformed messages are
counted and dropped (:class:`BagCounts`).
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np

from ext_sense_bags import BagError, BagReader
from ext_sense_perception.data.device_stream import match_truths
from ext_sense_perception.data.refractory import refractory_mask
from ext_sense_perception.data.window_set import WindowSet, file_hash, window_set_of
from ext_sense_perception.errors import PerceptionError
from ext_sense_perception.online.stage import WindowStage, events_of
from ext_sense_perception.online.window import ContactWindow, WindowConfig
from ext_sense_perception.profiles import OnsetSource
from ext_sense_runtime.enums import Sensor, Task
from ext_sense_runtime.records import EventBlock, GroundTruth, truth_of
from ext_sense_runtime.stamps import MS, S, stamp_to_ns

EVENTS_TYPE = "ext_sense_msgs/msg/TaxelEventBatch"
FRAMES_TYPE = "ext_sense_msgs/msg/BioTacFrame"
PACKETS_TYPE = "ext_sense_msgs/msg/SensorPacket"
TRUTH_TYPE = "ext_sense_msgs/msg/ContactGroundTruth"
ONSET_MODES = ("auto", "truth", "detected")
MARK_AHEAD_NS = 1 * S
"""Truth onsets are marked this far ahead of the data (longer than any sensor message)."""
SENSOR_ID_PEEK = 256
"""BioTac frames read to find the sensor ids when none are given."""


class BagTopics(NamedTuple):
    """Topic names to read; the defaults are the ones the recorder and the simulator write."""

    events: str = "/extsense/nuskin/events"
    frames: str = "/extsense/biotac/frames"
    truth: str = "/extsense/ground_truth"
    nuskin_packets: str = "/extsense/nuskin/packets"
    biotac_packets: str = "/extsense/biotac/packets"

    def streams(self, sensor: Sensor) -> tuple[str, str]:
        """The sensor's ``(packets, decoded)`` topics."""
        if sensor is Sensor.NUSKIN:
            return self.nuskin_packets, self.events
        return self.biotac_packets, self.frames


class BagCounts(NamedTuple):
    """What became of a bag's messages and windows.

    ``undecodable`` messages did not decode; ``bad_messages`` decoded but were malformed;
    ``truncated`` windows the bag ended inside; ``unmatched_windows`` had no truth near
    (``detected`` onsets); ``missed_truths`` got no window.
    """

    sensor_messages: int
    truths: int
    undecodable: int
    bad_messages: int
    windows: int
    truncated: int
    labelled: int
    unmatched_windows: int
    missed_truths: int


def _reader(path: Path) -> Any:
    try:
        return BagReader(path).open()
    except BagError as err:
        raise PerceptionError(f"The 'data' parameter must be a readable bag: {err}") from err


def _decoded(bag: Any, topic: str, drops: list[int]) -> Iterator[Any]:
    """Decoded messages of one topic in log-time order; undecodable ones counted in drops[0]."""
    try:
        for rec in bag.records([topic]):
            try:
                yield bag.decode(rec)
            except BagError:
                drops[0] += 1
    except BagError as err:
        raise PerceptionError(f"Cannot read topic {topic!r} of bag {bag.path}: {err}") from err


def _check_type(topics: dict[str, Any], topic: str, expected: str) -> None:
    got = topics[topic].msgtype
    if got != expected:
        raise PerceptionError(
            f"Topic {topic!r} must hold {expected}. Got {got} instead (use --events-topic, "
            "--frames-topic or --truth-topic to name another topic)."
        )


def _infer_sensor(topics: dict[str, Any], names: BagTopics, custom: dict[str, str]) -> Sensor:
    have = [s for s in (Sensor.NUSKIN, Sensor.BIOTAC) if any(t in topics for t in names.streams(s))]
    if "sensor" in custom:
        return Sensor.parse(custom["sensor"], PerceptionError)
    if len(have) == 1:
        return have[0]
    if not have:
        raise PerceptionError(
            f"The bag has no sensor topic: expected packets ({names.nuskin_packets!r}, "
            f"{names.biotac_packets!r}) or decoded arrays ({names.events!r}, TaxelEventBatch; "
            f"{names.frames!r}, BioTacFrame). Got topics {sorted(topics)} instead."
        )
    raise PerceptionError("The bag holds both sensors' streams: give --sensor nuskin or biotac.")


class _Refractory:
    """The per-taxel refractory drop of :func:`.refractory.refractory_mask`, across blocks."""

    def __init__(self, rate_hz: float, n_taxels: int) -> None:
        refractory_mask(np.zeros(0, np.int64), np.zeros(0, np.uint16), rate_hz)  # checks the rate
        self.rate_hz = rate_hz
        self.last = np.full(n_taxels + 2, np.iinfo(np.int64).min, dtype=np.int64)

    def __call__(self, events: EventBlock) -> EventBlock:
        if not events.size:
            return events
        slot = np.clip(events.taxel.astype(np.int64), 0, len(self.last) - 1)
        # each taxel's last kept spike goes first, so the drop continues across blocks
        prev = np.flatnonzero(self.last > np.iinfo(np.int64).min)
        prev = prev[np.isin(prev, slot)]
        t = np.concatenate([self.last[prev], events.t_ns])
        keep = refractory_mask(t, np.concatenate([prev, slot]), self.rate_hz)[len(prev) :]
        np.maximum.at(self.last, slot[keep], events.t_ns[keep])
        return events.select(keep)


def _sensor_ids(bag: Any, topic: str, packets: bool) -> tuple[int, ...]:
    """The BioTac sensor ids among the first frames (decoded from packets when ``packets``)."""
    from ext_sense_drivers.packets import PacketError, make_decoder

    ids: set[int] = set()
    decoder = None
    for k, msg in enumerate(_decoded(bag, topic, [0])):
        if packets:
            try:
                decoder = decoder or make_decoder(str(msg.encoding), str(msg.encoding_options))
                ids.update(int(f.sensor_id) for f in decoder.decode(msg).frames)
            except PacketError:
                pass  # counted when the windows are cut
        else:
            ids.add(int(msg.sensor_id))
        if k >= SENSOR_ID_PEEK:
            break
    return tuple(sorted(ids)) or (0,)


def window_set_from_bag(
    path: str | Path,
    task: str | Task | None = None,
    sensor: str | Sensor | None = None,
    *,
    topics: BagTopics = BagTopics(),  # noqa: B008  (an immutable NamedTuple)
    onsets: str = "auto",
    config: WindowConfig | None = None,
    rate_hz: float | None = None,
    sensor_ids: tuple[int, ...] | None = None,
    match_tolerance_ns: int = 300 * MS,
    require_labels: bool = True,
) -> tuple[WindowSet, BagCounts]:
    """Windows of a bag's sensor stream, labelled by its ground truth (``groups``: the trial).

    ``task`` and ``sensor`` default to the bag's ``custom_data``, else its ground truth and sensor
    topic; ``onsets`` is ``truth``, ``detected`` or ``auto`` (truth when the bag has any).
    ``rate_hz`` thins NUSkin events (BioTac decimates in the features); ``sensor_ids`` are the
    BioTac sensors joined into one window (default: those among the first frames).
    ``match_tolerance_ns`` bounds a detected onset's distance to its label's truth. PerceptionError:
    an unreadable or empty bag, a missing or mistyped topic, an unknown task or sensor, food without
    ground truth, or no labelled window when ``require_labels``.
    """
    path = Path(path)
    if onsets not in ONSET_MODES:
        raise PerceptionError(
            f"The 'onsets' parameter must be one of {', '.join(ONSET_MODES)}. Got {onsets!r} "
            "instead."
        )
    bag = _reader(path)
    try:
        have = bag.topics
        if bag.message_count == 0:
            raise PerceptionError(f"The bag {str(path)!r} holds no messages.")
        sensor_e = (
            Sensor.parse(sensor, PerceptionError)
            if sensor
            else _infer_sensor(have, topics, bag.custom_data)
        )
        packets, decoded = topics.streams(sensor_e)
        use_packets = packets in have and have[packets].count > 0
        stream = packets if use_packets else decoded
        if stream not in have or have[stream].count == 0:
            raise PerceptionError(
                f"The bag has no {sensor_e.label} messages on {packets!r} or {decoded!r}. Got "
                f"topics { {t: s.count for t, s in have.items()} } instead."
            )
        expected = EVENTS_TYPE if sensor_e is Sensor.NUSKIN else FRAMES_TYPE
        _check_type(have, stream, PACKETS_TYPE if use_packets else expected)
        drops = [0]
        truths: list[GroundTruth] = []
        if topics.truth in have:
            _check_type(have, topics.truth, TRUTH_TYPE)
            truths = [truth_of(msg) for msg in _decoded(bag, topics.truth, drops)]
        truth_task = next((g.task for g in truths if g.task), "")  # the first one's
        task_name = task or bag.custom_data.get("task") or truth_task
        if not task_name:
            raise PerceptionError(
                "The bag names no task (no custom_data 'task', no ground truth): give --task."
            )
        task_e = Task.parse(task_name, PerceptionError)
        mode = onsets if onsets != "auto" else ("truth" if truths else "detected")
        config = config or WindowConfig.for_task(task_e, sensor_e)
        live_profile = config.profile
        if config.task is not task_e or config.sensor is not sensor_e:
            raise PerceptionError(
                f"The 'config' parameter must be for {task_e.label}/{sensor_e.label}. Got "
                f"{config.task.label}/{config.sensor.label} instead."
            )
        if mode == "truth":
            if not truths:
                raise PerceptionError(
                    f"Onsets 'truth' need ground truth on {topics.truth!r}; the bag has none."
                )
            config = config.with_profile(onset_source=OnsetSource.EXTERNAL, debounce_ns=0)
        elif config.external_onsets:
            raise PerceptionError(
                f"{task_e.label} windows start at the arm's motion start, which a bag gives as "
                f"ground truth on {topics.truth!r}: use onsets 'truth' (got {mode!r}"
                + (", and the bag has no ground truth)." if not truths else ").")
            )
        config = config.with_profile(anytime_post_ns=())  # final windows only
        if sensor_e is Sensor.BIOTAC and sensor_ids is None:
            sensor_ids = _sensor_ids(bag, stream, use_packets)
        stage = WindowStage(config, sensor_ids or (0,))
        # truth onsets are marked just ahead of their data: a few pending windows, not all
        marks = np.sort([g.onset_ns - config.pre_ns for g in truths]) if mode == "truth" else []
        next_mark = 0
        nuskin_rate = rate_hz is not None and sensor_e is Sensor.NUSKIN
        thin = _Refractory(rate_hz, config.n_taxels) if nuskin_rate else None
        windows: list[ContactWindow] = []
        n_msgs = 0
        for msg in _decoded(bag, stream, drops):
            n_msgs += 1
            horizon = stamp_to_ns(msg.header.stamp) + MARK_AHEAD_NS
            while next_mark < len(marks) and marks[next_mark] <= horizon:
                stage.on_motion_start(int(marks[next_mark]) + config.pre_ns)
                next_mark += 1
            events = events_of(msg) if thin is not None and not use_packets else None
            if use_packets:
                windows.extend(stage.on_packet(msg, thin))
            elif events is not None:
                windows.extend(stage.on_block(thin(events), stamp_to_ns(msg.header.stamp)))
            elif sensor_e is Sensor.NUSKIN:
                windows.extend(stage.on_events(msg))
            else:
                windows.extend(stage.on_frame(msg))
        if n_msgs == 0:  # windows cut from ground truth alone would be all zeros
            raise PerceptionError(
                f"No message on {stream!r} of bag {str(path)!r} could be read ({drops[0]} "
                "undecodable): there is no sensor data to cut windows from."
            )
        for mark in marks[next_mark:]:
            stage.on_motion_start(int(mark) + config.pre_ns)
        if stage.last_data_ns is not None:
            windows.extend(stage.advance(stage.last_data_ns + config.post_ns))
        windows.extend(stage.flush())
        bad = int(stage.counters.bad_messages + stage.counters.bad_packets)
    finally:
        bag.close()
    finals = [w for w in windows if not w.provisional]
    if mode == "truth":
        by_stamp: dict[int, list[GroundTruth]] = {}
        for g in sorted(truths, key=lambda g: g.onset_ns):
            by_stamp.setdefault(g.onset_ns, []).append(g)
        pairs = [(w, by_stamp[w.onset_ns].pop(0)) for w in finals]
        unmatched, missed = 0, len(truths) - len(pairs)
    else:
        pairs, unmatched, missed = match_truths(finals, truths, match_tolerance_ns)
    counts = BagCounts(
        n_msgs,
        len(truths),
        drops[0],
        bad,
        len(finals),
        sum(w.truncated for w in finals),
        len(pairs),
        unmatched,
        missed,
    )
    if not pairs and require_labels:
        raise PerceptionError(
            f"No window of bag {str(path)!r} has a label ({len(finals)} windows, "
            f"{len(truths)} ground-truth messages, onsets {mode!r}); training needs ground truth."
        )
    if require_labels or truths:
        chosen = [w for w, _ in pairs]
        labels = [g.label for _, g in pairs]
        groups = np.asarray([g.trial for _, g in pairs], dtype=np.int64)
        rod = np.asarray([g.rod_length_m for _, g in pairs], dtype=np.float64)
    else:
        chosen = finals
        labels = [math.nan if task_e.is_regression else ""] * len(finals)
        groups = np.arange(len(finals), dtype=np.int64)
        rod = np.full(len(finals), np.nan)
    files = [path] if path.is_file() else sorted(p for p in path.iterdir() if p.is_file())
    ws = window_set_of(
        config,
        chosen,
        labels,
        str(path),
        file_hash(*files),
        groups=groups,
        rod_length_m=rod,
        n_channels=len(sensor_ids or (0,)) if sensor_e is Sensor.BIOTAC else None,
        profile=live_profile,
    )
    return ws, counts


def is_bag(path: str | Path) -> bool:
    """Whether ``path`` looks like a rosbag2 bag (``.mcap``/``.db3``, or a directory of one)."""
    path = Path(path)
    if path.is_file():
        return path.suffix in (".mcap", ".db3")
    if path.is_dir():
        return (path / "metadata.yaml").is_file() or any(
            p.suffix in (".mcap", ".db3") for p in path.iterdir()
        )
    return False
