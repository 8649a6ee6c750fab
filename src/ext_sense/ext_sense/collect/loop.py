"""The operator's loop of ``ext-sense collect``: wait for the graph's events, ask, keep or redo.

No rclpy: the loop sees the collector node through its event queue (:class:`Collector`), which
is spun in another thread, so recording never pauses while the operator thinks. A handover grasp
runs from its offer to the behaviour's decision that ends it; its windows are those whose onset
lies between the two. A grasp without a window is not asked about.
"""

from __future__ import annotations

import contextlib
import queue
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any, Protocol

from ext_sense.collect.graph import MATCH_SETTLE_S
from ext_sense.collect.session import (
    DISCARD,
    FOOD_CLASSES,
    HANDOVER_CLASSES,
    KEEP,
    QUIT,
    REDO,
    Answers,
    CollectError,
    CollectState,
    grasp_class,
    grasp_end,
    grasp_windows,
    match_truth,
    parse_class,
    parse_command,
    parse_decision,
)
from ext_sense_runtime.stamps import stamp_to_ns

MATCH_NS = 150_000_000
"""A detected contact and an independent truth (simulator, mocap) closer than this are one."""
START_TRIES = 10
"""Food: ``/food/start`` requests, 2 s apart, before collect gives up on a probe."""
GRASP_SETTLE_S = 1.5
"""After a grasp's end decision, how long its last windows may still be in flight."""


class Collector(Protocol):
    """What the loop needs of :class:`ext_sense.collect.node.CollectorNode`."""

    events: queue.Queue[tuple[str, Any]]

    def subscribers(self, topic: str) -> set[str]: ...  # noqa: D102

    def publishers(self, topic: str) -> set[str]: ...  # noqa: D102

    def matched_publishers(self, topic: str) -> int: ...  # noqa: D102

    def start_probe(self) -> None: ...  # noqa: D102

    def trigger_sim(self, task: str, label: str) -> None: ...  # noqa: D102


class TrialLoop:
    """One session's loop for its task (:meth:`tap`, :meth:`handover`, :meth:`food`).

    ``state`` is saved into the session directory ``out`` after every answer; tap labels come
    from ``truth_mode`` (``prompt``, ``sim`` or ``mocap``); ``classes`` are food's; ``sim``: the
    source is the simulator; with ``sim_trigger`` collect triggers each simulated grasp;
    ``food_note`` says why a food probe may have no live estimate.
    """

    def __init__(
        self,
        node: Collector,
        state: CollectState,
        out: Path,
        answers: Answers,
        truth_mode: str,
        classes: tuple[str, ...] = FOOD_CLASSES,
        sim: bool = False,
        sim_trigger: bool = False,
        food_note: str = "",
    ) -> None:
        self.node, self.state, self.out = node, state, out
        self.answers, self.truth_mode, self.classes, self.sim = answers, truth_mode, classes, sim
        self.sim_trigger, self.food_note = sim_trigger, food_note
        self.truths: list[tuple[int, str]] = []
        self.windows: list[int] = []
        self.truncated: set[int] = set()
        self.estimates: dict[int, str] = {}
        self.offers: list[int] = []
        self.motion: list[int] = []
        self.decisions: list[str] = []
        self.handover_decisions: list[tuple[int, str]] = []

    def pump(self, until: Callable[[], bool], timeout_s: float) -> bool:
        """Sort the collector's events until ``until()`` or the timeout."""
        end = time.monotonic() + timeout_s
        while True:
            while not self.node.events.empty():  # the one consumer: get_nowait cannot fail
                self._sort(*self.node.events.get_nowait())
            if until():
                return True
            if time.monotonic() > end:
                return False
            with contextlib.suppress(queue.Empty):
                self._sort(*self.node.events.get(timeout=0.05))

    def _sort(self, topic: str, msg: Any) -> None:
        stamp = stamp_to_ns(msg.header.stamp) if hasattr(msg, "header") else 0
        if topic == "/extsense/contact_window" and not msg.provisional:
            self.windows.append(stamp)
            if msg.truncated:
                self.truncated.add(stamp)
        elif topic == "/extsense/contact_estimate" and not msg.provisional:
            self.estimates[stamp] = estimate_text(msg)
        elif topic == "/extsense/sim/ground_truth":
            self.truths.append((stamp, msg.class_label or f"{msg.tap_position_m:.3f}"))
        elif topic == "mocap":
            p = msg.pose.position
            self.truths.append((stamp, f"{(p.x**2 + p.y**2 + p.z**2) ** 0.5:.3f}"))
        elif topic == "/extsense/handover/offer":
            self.offers.append(stamp)
        elif topic == "/extsense/motion_start":
            self.motion.append(stamp)
        elif topic == "/food/decision":
            self.decisions.append(msg.data)
        elif topic == "/handover/decision":
            self.handover_decisions.append(parse_decision(msg.data))

    def estimate_near(self, onset: int) -> str:
        """The live estimate of the window at ``onset`` (``""``: none yet or no model)."""
        est = match_truth(onset, list(self.estimates.items()), 5_000_000)
        truncated = any(abs(t - onset) <= 5_000_000 for t in self.truncated)
        return f"{est} (truncated window)" if est and truncated else est

    def _status(self, est: str = "") -> None:
        self.state.attempts += 1
        self.state.save(self.out)
        print(self.state.progress(est), flush=True)

    def _verdict(self, label: str, onsets: list[int], truth: str, est: str) -> str:
        """Ask keep/redo/discard/quit about one trial and apply it; returns the command."""
        while True:
            cmd = parse_command(self.answers.ask("  keep, redo, discard last, quit? [k/r/d/q]"))
            if cmd:
                break
        if cmd == KEEP:
            self.state.keep(label, onsets, truth)
        elif cmd == DISCARD:
            gone = self.state.discard_last()
            print(f"  discarded trial {gone.index if gone else '-'}; this one not kept")
        self._status(est)
        return cmd

    def tap(self) -> None:
        """Tap: prompt a position, show each detected contact, keep or redo it."""
        st, seen = self.state, 0
        while not st.done:
            target = float(st.prompt())
            where = f"tap at {100 * target:.1f} cm" if self.truth_mode == "prompt" else "tap"
            print(f"trial {len(st.trials) + 1} of {len(st.planned)}: {where}", flush=True)
            if not self.pump(lambda n=seen: len(self.windows) > n, 60.0):
                raise CollectError("no contact detected within 60 s: is the sensor streaming?")
            onset = self.windows[seen]
            seen += 1
            self.pump(lambda o=onset: bool(self.estimate_near(o)), 0.5)
            truth = match_truth(onset, self.truths, MATCH_NS)
            if self.truth_mode == "prompt":
                label = f"{target:.3f}"
            elif truth:
                label = truth
            else:
                print("  contact without a truth (mocap/simulator) near it: skipped")
                continue
            est = self.estimate_near(onset)
            print(
                f"  contact: label {100 * float(label):.1f} cm"
                + (f", estimate {est}" if est else "")
            )
            if self._verdict(label, [onset], truth, est) == QUIT:
                return

    def _next_grasp(self, k: int) -> tuple[int, int, list[int]]:
        """Wait for grasp ``k`` (the k-th offer) to end: its offer and end stamps, its onsets."""
        task = "handover_stability"
        if self.sim_trigger and k == 0:
            # the simulated device listens for triggers once its first grasp is simulated
            self._wait_for("/extsense/sim/trigger", {"sim_device"})
        if not self.pump(lambda: len(self.offers) > k, 60.0):
            raise CollectError("no handover offer within 60 s: are the behaviours running?")
        offer = self.offers[k]
        if self.sim_trigger:
            self.node.trigger_sim(task, grasp_class(self.answers.peek(), HANDOVER_CLASSES))
        if not self.pump(lambda: grasp_end(offer, self.handover_decisions) is not None, 120.0):
            raise CollectError("the handover did not end within 120 s (no RELEASED/TIMED_OUT)")
        end = grasp_end(offer, self.handover_decisions) or offer
        settle = time.monotonic() + GRASP_SETTLE_S
        self.pump(lambda: time.monotonic() > settle, GRASP_SETTLE_S + 1.0)
        return offer, end, grasp_windows(offer, end, self.windows)

    def handover(self) -> None:
        """Handover: after each grasp (its windows), the operator says stable or unstable."""
        st, classes, k = self.state, HANDOVER_CLASSES, 0
        while not st.done:
            print(f"grasp {len(st.trials) + 1} of {len(st.planned)}: hand over ({st.prompt()})")
            offer, end, onsets = self._next_grasp(k)
            k += 1
            if not onsets:
                print("  no contact window in this grasp: not asked, the next grasp is this trial")
                continue
            truth = next((label for t, label in self.truths if offer <= t <= end), "")
            ests = [e for e in (self.estimate_near(o) for o in onsets) if e]
            print(f"  {len(onsets)} contact windows; estimates {', '.join(ests) or 'none'}")
            while True:
                text = self.answers.ask("  stable, unstable, redo, discard last, quit?")
                cmd = parse_command(text)
                if cmd in (REDO, DISCARD, QUIT):
                    break
                try:
                    label = parse_class(text, classes)
                except CollectError as err:
                    print(f"  {err}")
                    continue
                st.keep(label, onsets, truth)
                break
            if cmd == DISCARD:
                st.discard_last()
            self._status(ests[-1] if ests else "")
            if cmd == QUIT:
                return

    def _wait_for(self, topic: str, nodes: set[str]) -> None:
        """Wait (90 s at most) until ``nodes`` subscribe to ``topic``: a trigger before is lost."""
        if not self.pump(lambda: nodes <= self.node.subscribers(topic), 90.0):
            missing = sorted(nodes - self.node.subscribers(topic))
            raise CollectError(f"{', '.join(missing)} did not subscribe to {topic} within 90 s")

    def _wait_for_publisher(self, topic: str, node: str) -> None:
        """Wait (90 s at most) until ``node`` publishes ``topic`` to the recording: none is lost."""
        seen = lambda: node in self.node.publishers(topic) and self.node.matched_publishers(topic)  # noqa: E731
        if not self.pump(seen, 90.0):
            raise CollectError(f"{node} did not publish {topic} within 90 s")
        self.pump(lambda: False, MATCH_SETTLE_S)  # the publisher's side may match a moment later

    def _start_probe(self, m: int, d: int) -> None:
        """Ask for a probe; again only while no decision answers (never a probe twice)."""
        for _ in range(START_TRIES):
            self.node.start_probe()
            if self.pump(lambda: len(self.decisions) > d or len(self.motion) > m, 2.0):
                return

    def food(self) -> None:
        """Food: the operator names the food, the behaviour lowers the fork, the window is kept."""
        st = self.state
        # the window node and (source sim) the simulated device hear each motion start before
        # the first probe (by name: other nodes of the graph may listen too)
        need = {"contact_window", "sim_device"} if self.sim else {"contact_window"}
        self._wait_for("/extsense/motion_start", need)
        if self.sim:
            # and the recording hears the simulator's truth of the first probe (it was lost
            # when the first probe started before the collector had found the simulator)
            self._wait_for_publisher("/extsense/sim/ground_truth", "sim_device")
        if self.food_note:
            print(f"[collect] note: {self.food_note}", flush=True)
        while not st.done:
            print(
                f"trial {len(st.trials) + 1} of {len(st.planned)}: put {st.prompt()} under "
                "the fork",
                flush=True,
            )
            text = self.answers.ask("  which food is it (or discard last, quit)?")
            cmd = parse_command(text)
            if cmd == QUIT:
                return
            if cmd == DISCARD:
                st.discard_last()
                self._status()
                continue
            try:
                food = parse_class(text, self.classes)
            except CollectError as err:
                print(f"  {err}")
                continue
            m, d = len(self.motion), len(self.decisions)
            self._start_probe(m, d)
            if not self.pump(lambda m=m: len(self.motion) > m, 20.0):
                raise CollectError("the food behaviour did not start a probe within 20 s")
            start = self.motion[m]
            # the label is stamped with the motion start whatever comes next; the window and the
            # estimate are only shown, and the probe must be over before the next one
            done = lambda d=d: any("DONE" in x or "FAULT" in x for x in self.decisions[d:])  # noqa: E731
            self.pump(lambda s=start, f=done: bool(self.estimate_near(s)) or f(), 20.0)
            self.pump(done, 30.0)
            truth = match_truth(start, self.truths, MATCH_NS)
            est = self.estimate_near(start)
            shown = est or ("none: " + self.food_note if self.food_note else "none")
            print(f"  probed {food}; estimate {shown}")
            st.keep(food, [start], truth)
            self._status(est)


def estimate_text(msg: Any) -> str:
    """A ``ContactEstimate`` as the terminal shows it."""
    if msg.class_label:
        return msg.class_label
    if msg.task == "handover_stability":
        return f"P(stable)={msg.stability_probability:.2f}"
    return f"{100 * msg.tap_position_m:.1f} cm"
