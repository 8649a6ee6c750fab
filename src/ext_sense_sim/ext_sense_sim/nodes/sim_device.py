"""``sim_device``: an emulated NUSkin or BioTac streaming a scene's bytes in real time.

Streams over a pty (with a symlink at ``port_link`` so a driver's ``port`` can name it before
it exists) or a python-can virtual channel, from a thread, and publishes ``ground_truth`` stamped
with the host time at which each trial's true onset bytes were written. The trials are
simulated ahead in a low-priority child process (:mod:`ext_sense_sim.trials_ahead`).

With ``mode`` = ``trigger`` the device is silent until a message on ``trigger`` (only its stamp
and ``class_label`` are used) asks for the next ``trials_per_trigger`` trials
(:func:`ext_sense_sim.streaming.stream_on_trigger`): e.g. the food probe's ``motion_start``
(``align`` = ``onset``) or the handover's ``handover/offer`` (``align`` = ``start``).
"""

from __future__ import annotations

import functools
import queue
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass

from rclpy.node import Node

from ext_sense_msgs.msg import ContactGroundTruth
from ext_sense_runtime.callback_guard import CallbackGuard
from ext_sense_runtime.diagnostics import Level, Updater
from ext_sense_runtime.diagnostics_ros import DiagnosticsPublisher
from ext_sense_runtime.node_main import run_node
from ext_sense_runtime.parameters import declare_all, param
from ext_sense_runtime.qos import COMMAND_QOS, GROUND_TRUTH_OFFERED_QOS
from ext_sense_runtime.records import GroundTruth
from ext_sense_runtime.stamps import fill_stamp, stamp_to_ns
from ext_sense_sim.links import open_link
from ext_sense_sim.scene import load_scene
from ext_sense_sim.streaming import (
    ALIGNS,
    DEVICE_PRIORITY,
    StreamStats,
    Trigger,
    stream,
    stream_on_trigger,
)

MODES = ("free", "trigger")
DEFAULT_SCENES = {"nuskin": "tap_rod30_nuskin", "biotac": "tap_rod30_biotac"}
_ro = functools.partial(param, read_only=True)


@dataclass(frozen=True)
class SimDeviceParameters:
    """``sim_device``'s parameters, all read-only."""

    device: str = _ro("nuskin", "Emulated sensor: nuskin or biotac.", choices=tuple(DEFAULT_SCENES))
    scene: str = _ro(
        "", "Shipped scene name or scene file path (empty: the 30 cm rod taps of the device)."
    )
    link: str = _ro("pty", "Link: pty or can.", choices=("pty", "can"))
    port_link: str = _ro("", "Path of a symlink to create to the pty (empty: none).")
    can_channel: str = _ro("ext_sense", "python-can virtual channel.")
    trials: int = _ro(0, "Trials to stream (0 = forever).", low=0, high=1_000_000)
    seed: int = _ro(0, "Seed of the stream.", low=0, high=2**31 - 1)
    trial_period_s: float = _ro(1.0, "Time between trial starts, s.", low=0.01, high=3600.0)
    wait_for_listener_s: float = _ro(
        0.0,
        "Mode free: before the first trial, wait up to this long for a subscriber to "
        "ground_truth (a monitor, which subscribes once it hears the estimates), s; 0: start "
        "at once.",
        low=0.0,
        high=3600.0,
    )
    listener_node: str = _ro(
        "",
        "With wait_for_listener_s: the node whose subscription to ground_truth starts the "
        "trials (e.g. estimate_monitor: a view or recorder listening first does not); empty: "
        "any subscriber.",
    )
    mode: str = _ro(
        "free",
        "free: trials every trial_period_s from start-up; trigger: trials_per_trigger "
        "trials per message on 'trigger'.",
        choices=MODES,
    )
    trials_per_trigger: int = _ro(
        1,
        "Trials played per trigger (mode trigger), their starts trial_period_s apart.",
        low=1,
        high=1000,
    )
    labels: str = _ro(
        "",
        "Class of the trials of successive triggers, comma separated, cycled (mode "
        "trigger; e.g. 'stable,unstable'; empty: as the scene draws them).",
    )
    align: str = _ro(
        "start",
        "Mode trigger: start (the trial starts on the trigger) or onset (its onset, e.g. "
        "the food motion start, is put at the trigger's stamp).",
        choices=ALIGNS,
    )


class SimDeviceNode(Node):
    """Emulated tactile device (see module docstring)."""

    PARAMETERS = SimDeviceParameters

    def __init__(self, **kwargs: object) -> None:
        super().__init__("sim_device", **kwargs)
        self.guard = CallbackGuard(self.get_logger().error)
        p = declare_all(self, SimDeviceParameters)
        device, link, can_channel = p.device, p.link, p.can_channel
        self.scene = load_scene(p.scene or DEFAULT_SCENES[device])
        if self.scene.sensor.label != device:
            raise ValueError(
                f"The 'scene' parameter names a {self.scene.sensor.label} scene "
                f"({self.scene.name}) but 'device' is {device!r}."
            )
        self.sink = open_link(
            link, link_path=p.port_link, can_channel=can_channel, priority=DEVICE_PRIORITY
        )
        self.port = getattr(self.sink, "path", f"can:{can_channel}")
        self.pub = self.create_publisher(
            ContactGroundTruth, "ground_truth", GROUND_TRUTH_OFFERED_QOS
        )
        self.stats = StreamStats()
        self.error = ""
        self._stop = threading.Event()
        updater = Updater(self.port)
        updater.add_check("stream", self._check)
        self.guard.attach(updater)
        self.diagnostics = DiagnosticsPublisher(self, updater)
        self.triggers: queue.Queue[Trigger] = queue.Queue()
        self.played = 0
        self._ready = threading.Event()
        self.listener_node = p.listener_node
        wait_ns = round(p.wait_for_listener_s * 1e9)
        self._listener_deadline_ns = time.monotonic_ns() + wait_ns if wait_ns else None
        common = dict(
            seed=p.seed,
            trials=p.trials,
            period_s=p.trial_period_s,
            on_onset=self._publish,
            stop=self._stop,
            stats=self.stats,
            ahead=True,
            priority=DEVICE_PRIORITY,
        )
        if p.mode == "trigger":
            run = functools.partial(
                stream_on_trigger,
                self.scene,
                self.sink.write,
                self.triggers,
                per_trigger=p.trials_per_trigger,
                labels=[x.strip() for x in p.labels.split(",") if x.strip()],
                align=p.align,
                on_ready=self._ready.set,
                **common,
            )
        else:
            run = functools.partial(
                stream, self.scene, self.sink.write, ready=self._listener_or_deadline, **common
            )
        self._thread = threading.Thread(
            target=self._run, args=(run,), name="sim_device", daemon=True
        )
        self._thread.start()
        if p.mode == "trigger":
            # listen once the first trial is simulated: a trigger before would be played late
            if not self._ready.wait(timeout=120.0) and not self.error:
                raise RuntimeError("sim_device: the first trial was not simulated within 120 s")
            self.create_subscription(
                ContactGroundTruth,
                "trigger",
                self.guard.wrap(
                    lambda m: self.triggers.put(
                        Trigger(stamp_to_ns(m.header.stamp), m.class_label)
                    ),
                    name="trigger",
                ),
                COMMAND_QOS,
            )
        self.get_logger().info(f"streaming scene {self.scene.name} on {self.port}")

    def _run(self, run: Callable[[], object]) -> None:
        try:
            run()
        except Exception as err:
            self.error = repr(err)
            self.get_logger().error(f"stream stopped: {err!r}")
        finally:
            self._ready.set()  # the trigger subscription waits for it

    def _listener_or_deadline(self) -> bool:
        """Whether the first trial may start: ground truth has a listener, or the wait is over."""
        deadline = self._listener_deadline_ns
        if deadline is None or self._listener_heard():
            return True
        if time.monotonic_ns() < deadline:
            return False
        self._listener_deadline_ns = None
        who = f"{self.listener_node}'s subscription" if self.listener_node else "a subscriber"
        self.get_logger().warning(
            f"no {who} to ground_truth within wait_for_listener_s: streaming anyway"
        )
        return True

    def _listener_heard(self) -> bool:
        """Whether ``listener_node`` (any node when empty) subscribes to ``ground_truth``."""
        name = self.listener_node
        if not name:
            return self.pub.get_subscription_count() > 0
        subscribers = self.get_subscriptions_info_by_topic(self.pub.topic_name)
        return any(info.node_name == name for info in subscribers)

    def _publish(self, gt: GroundTruth) -> None:
        msg = ContactGroundTruth(
            task=gt.task,
            trial=gt.trial,
            tap_position_m=gt.tap_position_m,
            rod_length_m=gt.rod_length_m,
            class_label=gt.class_label,
        )
        fill_stamp(msg.header.stamp, gt.onset_ns)
        msg.header.frame_id = self.scene.sensor.label
        self.pub.publish(msg)
        self.played += 1
        if self.played == 1:
            self.get_logger().info(f"pacing thread: {self.stats.extra.get('scheduling', '')}")
        self.get_logger().info(
            f"trial {gt.trial} ({gt.class_label or f'{gt.tap_position_m:.3f} m'}) onset at "
            f"{gt.onset_ns} ns (so far: {getattr(self.sink, 'dropped_bytes', 0)} bytes dropped, "
            f"{self.stats.extra.get('late_writes', 0)} of {self.stats.writes} writes > 2 ms late, "
            f"max {self.stats.extra.get('max_late_ns', 0) / 1e6:.1f} ms, "
            f"{self.stats.late_trials} trials started late: simulated after they were due)"
        )

    def _check(self) -> tuple[Level, str, dict[str, object]]:
        if self.error:
            return Level.ERROR, self.error, {}
        return (
            Level.OK,
            "streaming",
            {
                "trials": self.played,
                "dropped_bytes": getattr(self.sink, "dropped_bytes", 0),
                "skipped_bytes": self.stats.extra.get("skipped_bytes", 0),
                "late_writes": self.stats.extra.get("late_writes", 0),
                "max_late_ms": round(self.stats.extra.get("max_late_ns", 0) / 1e6, 2),
                "late_trials": self.stats.late_trials,
                "scheduling": self.stats.extra.get("scheduling", ""),
            },
        )

    def destroy_node(self) -> None:
        """Stop the stream thread and close the link."""
        self._stop.set()
        self._thread.join(timeout=2.0)
        self.sink.close()
        super().destroy_node()


def main(args: list[str] | None = None) -> int:
    """Run the node until shutdown."""
    return run_node(SimDeviceNode, args)
