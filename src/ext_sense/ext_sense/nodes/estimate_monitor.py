"""``estimate_monitor`` node: prints each estimate beside the simulator's ground truth.

After ``expected`` scored estimates (or ``idle_timeout_s`` without news once ``expected``
trials were seen) it prints the summary and shuts its context down, which ends the graph.

The monitor subscribes to ``ground_truth`` only once it hears an estimate publisher: a trial it
takes is one whose estimate it can hear. The simulated device waits for that subscriber before
its first trial (``sim_device`` ``wait_for_listener_s``), so under load, when discovery takes
seconds, no trial goes out before the graph can score it.
"""

from __future__ import annotations

import sys
import time
from dataclasses import dataclass
from typing import Any

import rclpy
from rclpy.node import Node

from ext_sense.nodes.scoreboard import Scoreboard
from ext_sense_msgs.msg import ContactEstimate, ContactGroundTruth
from ext_sense_runtime.callback_guard import CallbackGuard
from ext_sense_runtime.diagnostics import Level, Updater
from ext_sense_runtime.diagnostics_ros import DiagnosticsPublisher
from ext_sense_runtime.node_main import run_node
from ext_sense_runtime.parameters import declare_all, param
from ext_sense_runtime.qos import ESTIMATE_QOS, GROUND_TRUTH_QOS
from ext_sense_runtime.records import estimate_of, truth_of


@dataclass(frozen=True)
class MonitorParameters:
    """``estimate_monitor``'s parameters; the writable ones change live."""

    task: str = param("tap_localization", "Task whose estimates are scored.", read_only=True)
    expected: int = param(
        30,
        "Trials to score before printing the summary and exiting; 0: never exit.",
        low=0,
        high=1_000_000,
    )
    idle_timeout_s: float = param(
        5.0,
        "Once 'expected' trials were seen, stop after this long without a message, s.",
        low=0.1,
        high=3600.0,
    )
    give_up_s: float = param(
        30.0,
        "After any activity, stop after this long without "
        "a message even if trials are missing, s; 0: never.",
        low=0.0,
        high=86400.0,
    )
    match_tolerance_ms: float = param(
        300.0,
        "Largest onset difference between an estimate and its trial, ms.",
        low=1.0,
        high=10000.0,
    )
    show_provisional: bool = param(
        False, "Also print the provisional (anytime) estimates.", read_only=True
    )
    ground_truth: bool = param(
        True,
        "Trials come with ground truth (a simulator or a bag of one); false: count and print "
        "final estimates unscored, and stop after 'expected' of them.",
        read_only=True,
    )


class EstimateMonitorNode(Node):
    """Scores estimates against ground truth, prints them, stops after ``expected`` trials."""

    PARAMETERS = MonitorParameters

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(kwargs.pop("node_name", "estimate_monitor"), **kwargs)
        self.guard = CallbackGuard(self.get_logger().error)
        self.p = p = declare_all(self, MonitorParameters, self._on_change)
        self.show_provisional = p.show_provisional
        self.ground_truth = p.ground_truth
        self.board = Scoreboard(
            p.task, match_tolerance_ns=int(p.match_tolerance_ms * 1e6), ground_truth=p.ground_truth
        )
        self.trials_seen = 0
        self.done = False
        self._last_news = time.monotonic_ns()
        self._estimates = self.create_subscription(
            ContactEstimate, "contact_estimate", self.guard(self._on_estimate), ESTIMATE_QOS
        )
        if self.show_provisional:
            self.create_subscription(
                ContactEstimate,
                "contact_estimate/provisional",
                self.guard(self._on_estimate),
                ESTIMATE_QOS,
            )
        self._truths = None
        self.create_timer(0.2, self.guard(self._on_timer))
        self.updater = Updater(hardware_id=p.task)
        self.updater.add_check("score", self._check)
        self.guard.attach(self.updater)
        self.diagnostics = DiagnosticsPublisher(self, self.updater)

    def _on_change(self, new: MonitorParameters) -> None:
        self.p = new
        self.board.match_tolerance_ns = int(new.match_tolerance_ms * 1e6)

    def _print(self, lines: list[str]) -> None:
        for line in lines:
            print(line, flush=True)

    def _on_truth(self, msg: ContactGroundTruth) -> None:
        self.trials_seen += 1
        self._last_news = time.monotonic_ns()
        self._print(self.board.add_truth(truth_of(msg)))
        self._maybe_finish()

    def _on_estimate(self, msg: ContactEstimate) -> None:
        self._last_news = time.monotonic_ns()
        est = estimate_of(msg)
        if est.provisional and self.show_provisional:
            what = f"{est.tap_position_m * 100:.2f} cm {est.class_label}"
            print(f"  provisional @{est.post_contact_used_ns / 1e6:.0f} ms: {what}", flush=True)
        self._print(self.board.add_estimate(est))
        self._maybe_finish()

    def _listen_to_truth(self) -> None:
        """Subscribe to ``ground_truth`` once an estimate publisher is heard (module docstring)."""
        if self._truths is None and self._estimates.get_publisher_count() > 0:
            self._truths = self.create_subscription(
                ContactGroundTruth, "ground_truth", self.guard(self._on_truth), GROUND_TRUTH_QOS
            )

    def _on_timer(self) -> None:
        self._listen_to_truth()
        idle = time.monotonic_ns() - self._last_news
        # without ground truth the estimates are the trials
        seen = self.trials_seen if self.ground_truth else self.board.scored
        all_seen = self.p.expected and seen >= self.p.expected
        done = all_seen and idle > self.p.idle_timeout_s * 1e9
        stalled = self.p.give_up_s and seen and idle > self.p.give_up_s * 1e9
        if done or stalled:
            self._finish()

    def _maybe_finish(self) -> None:
        if self.p.expected and self.board.scored >= self.p.expected:
            self._finish()

    def _finish(self) -> None:
        if self.done:
            return
        self.done = True
        self.board.close()
        degraded = len(self.board.degraded)
        missed = max(0, self.trials_seen - self.board.scored - degraded)
        if degraded and self.ground_truth:  # a degraded estimate is neither scored nor missing
            print(f"degraded estimates (listed, not scored): {degraded}", flush=True)
        if self.ground_truth and (missed or self.board.unmatched_estimates):
            print(
                f"trials without estimate: {missed}; estimates without trial: "
                f"{self.board.unmatched_estimates}",
                flush=True,
            )
        print(self.board.summary(), flush=True)
        sys.stdout.flush()
        rclpy.try_shutdown(context=self.context)

    def _check(self) -> tuple[Level, str, dict[str, object]]:
        values = {
            "scored": self.board.scored,
            "trials_seen": self.trials_seen,
            "provisional_seen": self.board.provisional_seen,
        }
        return Level.OK, "ok", values


def main(args: list[str] | None = None) -> int:
    """Run the node (``ros2 run ext_sense estimate_monitor``)."""
    return run_node(EstimateMonitorNode, args)
