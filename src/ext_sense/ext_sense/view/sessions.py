"""What ``ext-sense plot`` draws, read from a bag or a folder of real captures (no ROS).

The sensor events on one timeline and the contacts on it. A bag's contacts are its final
windows (else its ground truths, else its estimates); a capture folder's trials are laid end to
end in capture order, at the arm's motion start where there is one, else the capture start.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np

from ext_sense.topics import SENSOR_PACKETS
from ext_sense.topics import TOPIC_ESTIMATE as ESTIMATES
from ext_sense.topics import TOPIC_GROUND_TRUTH as TRUTHS
from ext_sense.topics import TOPIC_WINDOW as WINDOWS
from ext_sense.view.errors import ViewError
from ext_sense.view.estimate import matching_truth
from ext_sense_runtime.records import Estimate, EventBlock, GroundTruth, estimate_of, truth_of
from ext_sense_runtime.stamps import MS, S, stamp_to_ns

MATCH_NS = 300 * MS
TRIAL_GAP_NS = S // 2
"""Space between two capture trials laid end to end, ns."""


class Contact(NamedTuple):
    """One contact: its onset, the span its window covers, and what is known about it.

    Times are ns on the session's timeline (food: the onset is the motion start); the final
    estimate and the truth are there when the source has them.
    """

    onset_ns: int
    start_ns: int
    end_ns: int
    name: str
    estimate: Estimate | None = None
    truth: GroundTruth | None = None


class PlotSession(NamedTuple):
    """A session to draw; ``task`` may be empty, ``contacts`` are in time order.

    BioTac events are one per frame on channel ``sensor_id + 1``, valued by the PAC's range.
    """

    name: str
    task: str
    sensor: str
    events: EventBlock
    contacts: list[Contact]


def load_session(path: str | Path) -> PlotSession:
    """A bag (directory, ``.mcap`` or ``.db3``) or a capture folder (``*_zero_*.tact``).

    Raises:
        ViewError: Neither, or it cannot be read.
    """
    path = Path(path)
    if not path.exists():
        raise ViewError(
            f"The 'source' argument must be a bag or a capture folder. Got '{path}': no such "
            "file or directory."
        )
    if path.is_dir() and any(path.glob("*_zero_*.tact")):
        return from_capture_folder(path)
    return from_bag(path)


def _span(task: str, sensor: str) -> tuple[int, int]:
    """The window's reach before and after its onset (the task profile's), ns."""
    from ext_sense_perception.profiles import profile_for

    try:
        prof = profile_for(task)
    except ValueError:
        return 50 * MS, 250 * MS
    return prof.pre_ns, prof.post_ns


def from_bag(path: Path) -> PlotSession:
    """Read a bag recorded from a graph (``ext-sense record``) or written by the tools."""
    from ext_sense_bags.errors import BagError
    from ext_sense_bags.reader import BagReader

    from ext_sense.offline_replay import packet_topic

    blocks: list[EventBlock] = []
    finals: list[tuple[int, int, int]] = []
    estimates: list[Estimate] = []
    truths: list[GroundTruth] = []
    sensor = "nuskin"
    decoders: dict[tuple[str, str, int], Any] = {}
    try:
        with BagReader(path) as bag:
            have = bag.topics
            sensor = _bag_sensor(have)
            packets = packet_topic(have, path, sensor)
            wanted = [t for t in (packets, WINDOWS, ESTIMATES, TRUTHS) if t in have]
            for rec, msg in bag.messages(wanted):
                if rec.topic == packets:
                    blocks += _packet_blocks(msg, decoders)
                elif rec.topic == WINDOWS and not msg.provisional:
                    onset = stamp_to_ns(msg.header.stamp)
                    finals.append(
                        (onset, onset - int(msg.pre_onset_ns), onset + int(msg.post_onset_ns))
                    )
                elif rec.topic == ESTIMATES:
                    est = estimate_of(msg)
                    if not est.provisional:
                        estimates.append(est)
                elif rec.topic == TRUTHS:
                    truths.append(truth_of(msg))
    except BagError as err:
        raise ViewError(f"Cannot plot {path}: {err}") from err
    events = EventBlock.concat(blocks).sorted_by_time()
    task = next((x.task for x in [*truths, *estimates] if x.task), "")
    pre, post = _span(task, sensor)
    spans = finals or [
        (o, o - pre, o + post)
        for o in [*(t.onset_ns for t in truths)] or [e.onset_ns for e in estimates]
    ]
    contacts = []
    for k, (onset, start, end) in enumerate(sorted(spans)):
        probe = Estimate(task, onset)
        est = matching_truth(probe, estimates, MATCH_NS)  # the nearest estimate, as a truth
        truth = matching_truth(probe, truths, MATCH_NS)
        name = f"trial {truth.trial}" if truth is not None else f"contact {k + 1}"
        contacts.append(Contact(onset, start, end, name, est, truth))
    return PlotSession(path.name, task, sensor, events, contacts)


def _bag_sensor(have: Any) -> str:
    """The bag's sensor: BioTac when it holds BioTac packets and no NUSkin ones."""
    nuskin, biotac = (SENSOR_PACKETS[s] in have for s in ("nuskin", "biotac"))
    return "biotac" if biotac and not nuskin else "nuskin"


def _packet_blocks(msg: Any, decoders: dict[tuple[str, str, int], Any]) -> list[EventBlock]:
    """One raw packet as plotted events (BioTac: one per frame, valued by its PAC range)."""
    from ext_sense_drivers.packets import PacketError, make_decoder

    key = (str(msg.encoding), str(msg.encoding_options), int(msg.connection))
    try:
        if key not in decoders:
            decoders[key] = make_decoder(key[0], key[1])
        decoded = decoders[key].decode(msg)
    except PacketError as err:
        raise ViewError(f"Cannot decode packet seq {msg.seq}: {err}") from err
    if hasattr(decoded, "frames"):
        return [
            EventBlock.of(
                [f.stamp_ns], [f.sensor_id + 1], value=[int(np.ptp(np.asarray(f.pac, np.int64)))]
            )
            for f in decoded.frames
        ]
    return [decoded.events]


def from_capture_folder(path: Path) -> PlotSession:
    """Read a folder of real NUSkin food-poking captures, trials end to end."""
    from ext_sense_perception.data.importers import food_poking_trials
    from ext_sense_perception.errors import PerceptionError

    try:
        try:
            recs, _ = food_poking_trials(path)
        except PerceptionError:  # a session without arm bags: onsets at the capture start
            recs, _ = food_poking_trials(path, arm_motion=False)
    except PerceptionError as err:
        raise ViewError(f"Cannot plot {path}: {err}") from err
    recs = sorted(recs, key=lambda r: r.capture_start_ns)
    task = "food_identification"
    pre, post = _span(task, "nuskin")
    blocks, contacts, cursor = [], [], 0
    for k, rec in enumerate(recs):
        first = min(rec.capture_start_ns, int(rec.events.t_ns.min()))
        shift = cursor - first
        blocks.append(rec.events._replace(t_ns=rec.events.t_ns + shift))
        onset = (rec.motion.start_ns if rec.motion is not None else rec.capture_start_ns) + shift
        truth = GroundTruth(k, onset, task, math.nan, rec.label)
        contacts.append(Contact(onset, onset - pre, onset + post, rec.name, None, truth))
        cursor = int(rec.events.t_ns.max()) + shift + TRIAL_GAP_NS
    return PlotSession(path.name, task, "nuskin", EventBlock.concat(blocks), contacts)
