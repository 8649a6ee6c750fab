"""Streaming a scene's device bytes in real time: the core shared by ``sim serve`` and the node.

Trial ``k`` starts ``k * period_s`` after the stream starts, and each of its wire chunks is
written when the host clock reaches the trial start plus the chunk's time. Each next trial is
simulated in the idle time before it is due (one simulated at its start would go out late, its
first bytes in one burst); one that is still late starts when it is ready, at its own pace, and
the trials after it keep their spacing (counted in ``late_trials``): a burst of overdue bytes is
a tap no receiver makes. When the first chunk at or after the true contact onset is written,
``on_onset`` gets the ground truth stamped with the host time (``time.time_ns``, the clock
drivers stamp arrival with) of that write.

The trials come from :mod:`~ext_sense_sim.trial_plan`, simulated here or, with ``ahead``, in a
low-priority child process (:mod:`~ext_sense_sim.trials_ahead`).
"""

from __future__ import annotations

import contextlib
import queue
import threading
import time
from collections.abc import Callable, Generator, Iterator
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np

from ext_sense_drivers.transports.scheduling import raise_thread_priority
from ext_sense_runtime.enums import Sensor
from ext_sense_runtime.records import GroundTruth
from ext_sense_sim.bridge_line import BridgeLine
from ext_sense_sim.errors import SceneError
from ext_sense_sim.scene import Scene
from ext_sense_sim.trial_plan import PlannedTrial, plan_trials, require_wire
from ext_sense_sim.trials_ahead import TrialsAhead


@dataclass
class StreamStats:
    """Counters of a stream."""

    trials: int = 0
    bytes: int = 0
    writes: int = 0
    late_trials: int = 0
    extra: dict = field(default_factory=dict)


def stream(
    scene: Scene,
    write: Callable[[bytes], object],
    *,
    seed: int,
    trials: int = 0,
    period_s: float = 1.0,
    on_onset: Callable[[GroundTruth], None] | None = None,
    stop: threading.Event | None = None,
    clock: Callable[[], int] = time.time_ns,
    sleep: Callable[[float], None] = time.sleep,
    stats: StreamStats | None = None,
    ahead: bool = False,
    priority: int = 0,
    ready: Callable[[], bool] | None = None,
) -> StreamStats:
    """Write the scene's device bytes in real time until ``trials`` are done or ``stop`` is set.

    ``write`` sends bytes to the link; ``trials`` 0 streams until stopped; ``period_s`` is at
    least the trial length; ``clock`` (epoch ns) and ``sleep`` are injectable for tests;
    ``stats`` fills as it goes (a node's diagnostics read it). ``ahead`` simulates the same
    trials in a low-priority child process. ``priority``: the SCHED_FIFO priority the calling
    thread asks for while it paces the bytes (0: as it is), as hardware is not slowed by a
    loaded host; what it got is in ``stats.extra["scheduling"]``. ``ready`` is polled every
    5 ms once the first trial is simulated, which waits for it (e.g. a ground-truth listener).
    """
    stop = stop or threading.Event()
    stats = StreamStats() if stats is None else stats
    _take_priority(priority, stats)
    period_ns = round(max(period_s, scene.trial_s) * 1e9)
    rod = scene.geometry.length_m if scene.geometry.kind == "rod" else float("nan")
    with _trials(scene, seed, stop, ahead) as plans:
        start: int | None = None
        delay_ns = 0  # how far late trials have pushed the schedule
        upcoming: PlannedTrial | None = next(plans, None)
        line, bridge = _device_line(scene, write, clock, stats)
        if bridge is not None and upcoming is not None:
            bridge.prime(b"".join(c[1] for c in upcoming.chunks[:4]))
        while upcoming is not None:
            plan = upcoming
            if stop.is_set() or (trials and plan.trial >= trials):
                break
            if start is None:  # the first trial is simulated before the clock starts
                while ready is not None and not ready() and not stop.is_set():
                    line.idle()
                    sleep(0.005)
                start = clock()
            t0 = start + plan.trial * period_ns + delay_ns
            now = clock()
            if now > t0:
                stats.late_trials += now - t0 > LATE_WRITE_NS
                delay_ns += now - t0
                t0 = now
            _play(plan, t0, line.write, stats, scene, rod, on_onset, stop, clock, sleep)
            stats.trials += 1
            last = bool(trials) and plan.trial + 1 >= trials
            upcoming = None if last or stop.is_set() else next(plans, None)  # in the idle time
            # the bridge keeps sending through the last period too: the last window closes on data
            while not stop.is_set() and clock() < t0 + period_ns and (not last or bridge):
                line.idle()
                sleep(min(0.005, max(0.0, (t0 + period_ns - clock()) / 1e9)))
    return stats


def _take_priority(priority: int, stats: StreamStats) -> None:
    if priority > 0:
        stats.extra["scheduling"] = raise_thread_priority(priority).describe()


@contextlib.contextmanager
def _trials(
    scene: Scene, seed: int, stop: threading.Event, ahead: bool
) -> Generator[Iterator[PlannedTrial]]:
    """The scene's trials, simulated here or (``ahead``) in a child process ended on exit."""
    if not ahead:
        yield plan_trials(scene, seed)
        return
    require_wire(scene)  # a clear error at once, not from the child
    with TrialsAhead(scene, seed, stop) as plans:
        yield plans


class _Line(NamedTuple):
    """What the stream writes trials with, and what it calls while it waits between them."""

    write: Callable[[bytes], object]
    idle: Callable[[], object]


def _device_line(
    scene: Scene, write: Callable[[bytes], object], clock: Callable[[], int], stats: StreamStats
) -> tuple[_Line, BridgeLine | None]:
    """How a scene's trials reach the link.

    A BioTac scene streams through a :class:`~ext_sense_sim.bridge_line.BridgeLine` (rest frames
    between trials); a NUSkin one, or one that corrupts its wire on purpose, as it is.
    """
    faults = any(name == "wire_faults" for name, _ in scene.effects)
    if scene.sensor is not Sensor.BIOTAC or faults:
        return _Line(write, lambda: None), None
    line = BridgeLine(write, clock)

    def idle() -> None:
        written = line.idle()
        if written:
            stats.bytes += written
            stats.writes += 1
            stats.extra["rest_frames"] = line.rest_frames

    return _Line(line.write, idle), line


DEVICE_PRIORITY = 60
"""SCHED_FIFO priority of a live emulated device's pacing and pty writer threads: above a
driver's reader (``reader_priority`` 50), as hardware is never late for the host's load."""

FRAME_NS = 1_000_000
"""A device writes at most once a millisecond, all that is due: a USB full-speed link delivers
in 1 ms frames, and the training streams are read in 1 ms ticks
(:mod:`ext_sense_perception.data.device_stream`). Word by word (every 21 us at the receiver's
48k words/s), a real-time device woke tens of thousands of times a second and delayed the hot
path it feeds."""

LATE_WRITE_NS = 2_000_000
"""A write whose oldest chunk is due more than this long ago counts in ``late_writes``."""


class Trigger(NamedTuple):
    """A request to play the next trial(s) now: ``stamp_ns`` on the host epoch clock.

    ``label`` (``""``: the schedule's) is the class to play, so whoever triggers can keep the
    scene in step with what it knows only then (``ext-sense collect`` replays a missed class).
    """

    stamp_ns: int
    label: str = ""


ALIGNS = ("start", "onset")


class _StoppedError(Exception):
    """The stream was stopped while it waited for its next trial (simulated ahead)."""


def _next_like(plans: Iterator[PlannedTrial], label: str, scene: Scene) -> PlannedTrial:
    """The next planned trial of class ``label`` ("" = the next one)."""
    for _ in range(1000):
        plan = next(plans, None)
        if plan is None:
            raise _StoppedError
        if not label or plan.class_label == label:
            return plan
    raise SceneError(
        f"Scene '{scene.name}' gave no trial labelled {label!r} in 1000 trials; the 'labels' "
        f"parameter must name the scene's classes."
    )


def _wait_trigger(
    triggers: queue.Queue[Trigger], stop: threading.Event, idle: Callable[[], object]
) -> Trigger | None:
    """The next trigger, or ``None`` once ``stop`` is set; ``idle`` runs every 5 ms meanwhile."""
    while not stop.is_set():
        idle()
        try:
            return triggers.get(timeout=0.005)
        except queue.Empty:
            continue
    return None


def stream_on_trigger(
    scene: Scene,
    write: Callable[[bytes], object],
    triggers: queue.Queue[Trigger],
    *,
    seed: int,
    trials: int = 0,
    per_trigger: int = 1,
    period_s: float = 1.0,
    labels: list[str] | None = None,
    align: str = "start",
    on_onset: Callable[[GroundTruth], None] | None = None,
    on_ready: Callable[[], None] | None = None,
    stop: threading.Event | None = None,
    clock: Callable[[], int] = time.time_ns,
    sleep: Callable[[float], None] = time.sleep,
    stats: StreamStats | None = None,
    ahead: bool = False,
    priority: int = 0,
) -> StreamStats:
    """Play ``per_trigger`` trials per trigger, silent in between: a behaviour drives the scene.

    The triggers are a food probe's motion start or a handover's offer. The trials of one
    trigger are ``period_s`` apart and, with ``labels``, all of the class
    ``labels[k % len(labels)]`` for the k-th trigger, or the trigger's own ``label`` (trials of
    other classes are skipped, so the seed still fixes everything). ``align="start"``: the first
    trial starts when the trigger is taken. ``align="onset"``: its onset is put at the trigger's
    stamp; its bytes before the onset are skipped (``extra["skipped_bytes"]``), those from the
    onset to now go out at once, and the ground truth carries the trigger's stamp. The next
    trial is simulated while waiting for its trigger; ``on_ready`` is called each time it waits
    (a trigger that comes earlier is played late). The other arguments are :func:`stream`'s.

    Raises:
        SceneError: Bad ``align`` or ``per_trigger``, the scene lacks the wire effect, or no
            trial of a scheduled label.
    """
    if align not in ALIGNS:
        raise SceneError(f"The 'align' parameter must be one of {ALIGNS}. Got {align!r} instead.")
    if per_trigger < 1:
        raise SceneError(f"The 'per_trigger' parameter must be >= 1. Got {per_trigger!r} instead.")
    stop = stop or threading.Event()
    stats = StreamStats() if stats is None else stats
    _take_priority(priority, stats)
    labels = list(labels or [])
    period_ns = round(max(period_s, scene.trial_s) * 1e9)
    stats.extra.update(skipped_bytes=0, triggers=0)
    rod = scene.geometry.length_m if scene.geometry.kind == "rod" else float("nan")
    played = 0
    with _trials(scene, seed, stop, ahead) as plans, contextlib.suppress(_StoppedError):
        line, bridge = _device_line(scene, write, clock, stats)
        primed = False
        while not stop.is_set() and not (trials and played >= trials):
            # simulated before the trigger comes, so it can start at once
            label = labels[stats.extra["triggers"] % len(labels)] if labels else ""
            plan = _next_like(plans, label, scene)
            if bridge is not None and not primed:
                bridge.prime(b"".join(c[1] for c in plan.chunks[:4]))
                primed = True
            if on_ready is not None:
                on_ready()
            trigger = _wait_trigger(triggers, stop, line.idle)
            if trigger is None:
                break
            stats.extra["triggers"] += 1
            if trigger.label and trigger.label != plan.class_label:
                plan = _next_like(plans, trigger.label, scene)  # simulated late: played late
            t0 = trigger.stamp_ns - plan.onset_ns if align == "onset" else clock()
            for j in range(per_trigger):
                start = t0 + j * period_ns
                now = clock()
                if j and now > start:  # simulated late: it starts when ready (see stream)
                    stats.late_trials += now - start > LATE_WRITE_NS
                    t0 += now - start
                    start = now
                onset_only = align == "onset" and j == 0
                _play(
                    plan,
                    start,
                    line.write,
                    stats,
                    scene,
                    rod,
                    on_onset,
                    stop,
                    clock,
                    sleep,
                    skip_before_onset=onset_only,
                    truth_stamp_ns=trigger.stamp_ns if onset_only else None,
                )
                played += 1
                stats.trials += 1
                if stop.is_set() or (trials and played >= trials):
                    break
                if j + 1 < per_trigger:
                    # one grasp's trials share their class; simulated in the idle time
                    same = labels or trigger.label
                    plan = _next_like(plans, plan.class_label if same else "", scene)
                    while not stop.is_set() and clock() < start + period_ns:
                        line.idle()
                        sleep(min(0.005, max(0.0, (start + period_ns - clock()) / 1e9)))
        if bridge is not None and played:  # the last window closes on data (see stream)
            end = clock() + period_ns
            while not stop.is_set() and clock() < end:
                line.idle()
                sleep(0.005)
    return stats


def _play(
    plan: PlannedTrial,
    t0: int,
    write: Callable[[bytes], object],
    stats: StreamStats,
    scene: Scene,
    rod: float,
    on_onset: Callable[[GroundTruth], None] | None,
    stop: threading.Event,
    clock: Callable[[], int],
    sleep: Callable[[float], None],
    *,
    skip_before_onset: bool = False,
    truth_stamp_ns: int | None = None,
) -> None:
    """Write one trial's chunks when the clock reaches ``t0`` plus each chunk's time."""
    times = np.array([c[0] for c in plan.chunks], dtype=np.int64)
    onset_index = int(np.searchsorted(times, plan.onset_ns))
    i = 0
    if skip_before_onset and clock() > t0 + plan.onset_ns:
        i = onset_index
        stats.extra["skipped_bytes"] = stats.extra.get("skipped_bytes", 0) + sum(
            len(c[1]) for c in plan.chunks[:i]
        )
    sent_onset = False
    next_write_ns = 0
    while i < times.size and not stop.is_set():
        now = clock()
        if now < next_write_ns:
            sleep((next_write_ns - now) / 1e9)
            continue
        j = int(np.searchsorted(times, now - t0, side="right"))
        if j <= i:
            sleep(min(0.001, max(0.0, (t0 + int(times[i]) - now) / 1e9)))
            continue
        data = b"".join(c[1] for c in plan.chunks[i:j])
        write(data)
        next_write_ns = now + FRAME_NS
        stats.bytes += len(data)
        stats.writes += 1
        # how late the oldest chunk of this write is (a late device sends bursts the driver's
        # arrival clock spreads); the first write of an onset-aligned trial is late by design
        if sent_onset or not skip_before_onset:
            late = now - (t0 + int(times[i]))
            if late > LATE_WRITE_NS:
                stats.extra["late_writes"] = stats.extra.get("late_writes", 0) + 1
            stats.extra["max_late_ns"] = max(stats.extra.get("max_late_ns", 0), late)
        if not sent_onset and j > onset_index:
            sent_onset = True
            if on_onset is not None:
                on_onset(
                    GroundTruth(
                        plan.trial,
                        clock() if truth_stamp_ns is None else truth_stamp_ns,
                        scene.task.label,
                        plan.tap_position_m,
                        plan.class_label,
                        rod,
                    )
                )
        i = j
