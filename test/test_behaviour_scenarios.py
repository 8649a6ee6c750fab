"""Handover and food scenarios end to end over ROS (issue 8): the real node graph
(``ext-sense run GRAPH behaviours:=true``) on the emulated sensor, gripper and arm.

- Handover: ``sim_device`` plays a simulated person's grasp (``grasp_trials`` trials of one
  class) each time ``handover_behaviour`` offers the object; ``nuskin_driver`` ->
  ``contact_window`` -> ``contact_inference`` (a model trained on the simulator's own stream)
  -> ``handover_behaviour`` -> ``robotiq_gripper`` -> Modbus RTU on a pty -> the Robotiq
  emulator in this process, whose finger position and received commands are the evidence.
- Food: ``food_behaviour`` lowers its simulated arm at 1 cm/s; its ``motion_start`` both cuts
  the window in ``contact_window`` and makes ``sim_device`` play a food trial with its motion
  start put at the probe's; the arm stops on 10 N, the trained model classifies, the arm
  retracts and ``food/result`` is published.

The claims are about the behaviour (what opens the gripper, where the fork stops, which
window is classified), not about model accuracy: the per-trial P(stable) measured live is
printed (``pytest -s``) and recorded in docs/behaviours.md.
"""

from __future__ import annotations

import os
import re
import subprocess
import threading
import time
from pathlib import Path

import pytest
from rosutil import spinning, wait_for
from sim_models import EXE, stop_graph, stop_problems, train_sim_model

from ext_sense_runtime.stamps import MS, stamp_to_ns

pytestmark = [pytest.mark.ros, pytest.mark.slow, pytest.mark.timeout(300)]

DECISION = re.compile(r"^\[(\d+)\] ([A-Z_]+): ([A-Z_]+) - (.+)$")
THRESHOLD, CONSECUTIVE = 0.8, 3
OBJECT_POSITION = 128


def _stamp(msg) -> int:
    return stamp_to_ns(msg.header.stamp)


def _start_graph(graph: str, *args: str) -> subprocess.Popen:
    return subprocess.Popen(
        [*EXE, "run", graph, "monitor:=false", "seed:=5", *args],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        start_new_session=True,
    )


def _stop_graph(proc: subprocess.Popen) -> str:
    """Stop the runner and every node (its process group); returns its stderr (the logs)."""
    return stop_graph(proc)[1]


class Recorder:
    """A node in this process recording what the graph publishes: ``{topic: [(recv_ns, msg)]}``."""

    def __init__(self, topics: dict[str, type]) -> None:
        self.topics = topics
        self.got: dict[str, list] = {t: [] for t in topics}

    def __call__(self, context):
        import rclpy

        from ext_sense_runtime.qos import (
            COMMAND_QOS,
            DECISION_QOS,
            ESTIMATE_QOS,
            GROUND_TRUTH_OFFERED_QOS,
        )

        by_name = {
            "contact_estimate": ESTIMATE_QOS,
            # latched as the simulated device offers it: its first truth may precede the match
            "ground_truth": GROUND_TRUTH_OFFERED_QOS,
            "decision": DECISION_QOS,  # latched: the first decision may precede the match
        }
        node = rclpy.create_node("scenario_recorder", context=context)
        for topic, kind in self.topics.items():
            qos = by_name.get(topic.rsplit("/", 1)[-1], COMMAND_QOS)
            node.create_subscription(
                kind, topic, lambda m, t=topic: self.got[t].append((time.time_ns(), m)), qos
            )
        return node

    def decisions(self, topic: str) -> list[tuple[int, str, str, str]]:
        out = []
        for _, msg in self.got[topic]:
            match = DECISION.match(msg.data)
            assert match, f"decision without state, action and reason: {msg.data!r}"
            out.append((int(match[1]), match[2], match[3], match[4]))
        return out


@pytest.fixture(scope="module")
def handover_model(tmp_path_factory):
    """A handover model trained on the simulator's own stream (as ``ext-sense demo`` does)."""
    from ext_sense_perception.data.device_stream import window_set_from_stream
    from ext_sense_perception.online.window import WindowConfig
    from ext_sense_perception.training.recipe import train_bundle
    from ext_sense_sim.scene import load_scene
    from ext_sense_sim.trial_plan import lay_out_stream

    out = tmp_path_factory.mktemp("scenario_models") / "handover"
    if os.environ.get("EXT_SENSE_SCENARIO_HANDOVER_MODEL"):  # reuse a model between runs
        return Path(os.environ["EXT_SENSE_SCENARIO_HANDOVER_MODEL"])
    laid = lay_out_stream(load_scene("handover_rod_nuskin"), 1000, 80, 1.0)
    ws, counts = window_set_from_stream(
        laid.writes, laid.truths, WindowConfig.for_task("handover_stability", "nuskin")
    )
    assert counts.labelled >= 75, counts
    train_bundle(ws, str(out))
    return out


@pytest.fixture(scope="module")
def food_model(tmp_path_factory):
    """A food model trained on a small simulated set (as test_end_to_end does)."""
    model, _ = train_sim_model(
        tmp_path_factory.mktemp("scenario_food"), "food_fork_nuskin", "food_identification", 14
    )
    return model


class FingerLog:
    """The emulated gripper's side: every command it received and its finger position."""

    def __init__(self, emulator) -> None:
        self.model = emulator.model
        self.commands: list[tuple[int, int, bool]] = []  # (ns, rPR, rGTO)
        self.positions: list[tuple[int, float]] = []
        write = self.model.write

        def logged(command, now):
            self.commands.append((time.time_ns(), command.position, command.go_to))
            return write(command, now)

        self.model.write = logged
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._sample, daemon=True)
        self._thread.start()

    def _sample(self) -> None:
        while not self._stop.wait(0.02):
            self.positions.append((time.time_ns(), float(self.model.position)))

    def stop(self) -> None:
        self._stop.set()
        self._thread.join(timeout=2)

    def position_at(self, t_ns: int) -> float:
        before = [p for t, p in self.positions if t <= t_ns]
        return before[-1] if before else float("nan")


def _handovers(decisions):
    """Split the decision log into handovers: (offer ns, end ns, end state, its decisions)."""
    out, current = [], None
    for d in decisions:
        stamp, state, action, _ = d
        if state == "HOLDING" and action == "HOLD":
            current = [stamp, None, None, [d]]
            continue
        if current is None:
            continue
        current[3].append(d)
        if state in ("RELEASED", "TIMED_OUT", "FAULT") and current[1] is None:
            current[1], current[2] = stamp, state
            out.append(tuple(current))
            current = None
    return out


def test_handover_opens_only_on_stable_grasps(handover_model, tmp_path):
    from std_msgs.msg import String

    from ext_sense_msgs.msg import ContactEstimate, ContactGroundTruth
    from ext_sense_sim.devices.robotiq_emulator import GripperModel, PtyGripper, RobotiqEmulator

    grasps, per_grasp = 4, 6
    emulator = RobotiqEmulator(GripperModel(activation_s=0.05, object_position=OBJECT_POSITION))
    recorder = Recorder(
        {
            "/handover/decision": String,
            "/extsense/ground_truth": ContactGroundTruth,
            "/extsense/contact_estimate": ContactEstimate,
        }
    )
    with PtyGripper(emulator) as pty, spinning(recorder):
        fingers = FingerLog(emulator)
        proc = _start_graph(
            "handover",
            "behaviours:=true",
            f"model:={handover_model}",
            f"gripper_port:={pty.path}",
            f"port:={tmp_path / 'nuskin.pty'}",
            f"trials:={grasps * per_grasp}",
            f"grasp_trials:={per_grasp}",
            "sim_labels:=stable,unstable",
            "handover_timeout_s:=8",
        )
        try:
            done = wait_for(
                lambda: len(_handovers(recorder.decisions("/handover/decision"))) >= grasps,
                timeout=90,
                step=0.2,
            )
            time.sleep(0.5)  # let an opening finish
        finally:
            logs = _stop_graph(proc)
            fingers.stop()
    decisions = recorder.decisions("/handover/decision")
    handovers = _handovers(decisions)
    (tmp_path / "graph.log").write_text(logs)
    counts = {t: len(v) for t, v in recorder.got.items()}
    assert done, f"{len(handovers)} of {grasps} handovers ended, {counts}: {tmp_path / 'graph.log'}"
    assert not stop_problems(proc, "", logs), stop_problems(proc, "", logs)
    truths = [(_stamp(m), m.class_label) for _, m in recorder.got["/extsense/ground_truth"]]
    finals = [
        (_stamp(m), m.stability_probability)
        for _, m in recorder.got["/extsense/contact_estimate"]
        if not m.provisional
    ]
    opens = [(t, pr) for t, pr, go in fingers.commands if go and pr == 0]
    print("\nhandover  grasp     end        P(stable) of its final estimates")
    opened_stable = 0
    per_class: dict[str, list[float]] = {"stable": [], "unstable": []}
    for k, (offer, end, state, its) in enumerate(handovers[:grasps]):
        labels = {label for t, label in truths if offer <= t <= end}
        ps = [p for t, p in finals if offer <= t <= end]
        # '*': a window no trial onset explains (nearest ground truth more than 20 ms away)
        extra = [
            min((abs(t - g) for g, _ in truths), default=10**12) > 20 * MS
            for t, _ in ((t, p) for t, p in finals if offer <= t <= end)
        ]
        shown = " ".join(f"{p:.2f}{'*' if x else ''}" for p, x in zip(ps, extra, strict=True))
        print(f"{k:8d}  {','.join(sorted(labels)) or '-':9s} {state:10s} {shown}")
        assert len(labels) == 1, (labels, its)  # one person's grasp: one class
        (label,) = labels
        per_class[label] += ps
        opened = [t for t, _ in opens if offer <= t <= end + 10**9]
        assert all(reason.strip() for *_, reason in its)  # every decision has its reason
        run = _first_run(ps)
        if label == "unstable":
            # never opened on an unstable grasp: no open command reached the gripper, and the
            # fingers stayed on the object
            assert not opened, its
            assert state == "TIMED_OUT", its
            assert all(
                abs(p - OBJECT_POSITION) < 1 for t, p in fingers.positions if offer <= t <= end
            )
        elif run is not None:
            # a stable grasp seen as stable CONSECUTIVE times in a row: opened then, once,
            # and the fingers are open (the emulator's own position)
            assert state == "RELEASED", its
            release = next(d for d in its if d[2] == "OPEN_GRIPPER")
            assert f"for {CONSECUTIVE} consecutive estimates" in release[3]
            assert release[3].startswith(f"P(stable)={ps[run]:.3f}"), (release, ps)
            assert len(opened) == 1, opened
            assert fingers.position_at(end + 5 * 10**8) <= 10
            opened_stable += 1
        else:
            # a stable grasp the model never saw as stable CONSECUTIVE times in a row (finite
            # accuracy): the gripper kept holding, as it must
            assert not opened, its
            assert state == "TIMED_OUT", its
    # the gripper opened only during stable grasps, each time after the streak
    assert len(opens) == opened_stable, opens
    for label, ps in per_class.items():
        share = sum(p >= THRESHOLD for p in ps) / max(len(ps), 1)
        print(f"{label}: {len(ps)} final estimates, P(stable) >= {THRESHOLD}: {share:.0%}")
    print(f"stable grasps released: {opened_stable} of {grasps // 2}")


def _first_run(ps: list[float]) -> int | None:
    """Index of the estimate completing the first run of CONSECUTIVE >= THRESHOLD, if any."""
    streak = 0
    for i, p in enumerate(ps):
        streak = streak + 1 if p >= THRESHOLD else 0
        if streak >= CONSECUTIVE:
            return i
    return None


def test_food_probe_stops_on_contact_and_classifies_its_own_window(food_model, tmp_path):
    from sensor_msgs.msg import JointState
    from std_msgs.msg import String

    from ext_sense_msgs.msg import ContactEstimate, ContactGroundTruth, ContactWindow

    recorder = Recorder(
        {
            "/food/decision": String,
            "/food/result": ContactEstimate,
            "/arm/state": JointState,
            "/extsense/ground_truth": ContactGroundTruth,
            "/extsense/contact_window": ContactWindow,
        }
    )
    with spinning(recorder):
        proc = _start_graph(
            "food_identification",
            "behaviours:=true",
            f"model:={food_model}",
            f"port:={tmp_path / 'nuskin.pty'}",
            "trials:=1",
            "sim_labels:=apple",
        )
        try:
            done = wait_for(lambda: recorder.got["/food/result"], timeout=60, step=0.2)
        finally:
            logs = _stop_graph(proc)
    (tmp_path / "graph.log").write_text(logs)
    counts = {t: len(v) for t, v in recorder.got.items()}
    assert done, f"{counts}\n{tmp_path / 'graph.log'}"
    assert not stop_problems(proc, "", logs), stop_problems(proc, "", logs)
    decisions = recorder.decisions("/food/decision")
    states = [d[1] for d in decisions]
    assert states[:2] == ["LOWERING", "COLLECTING"], decisions
    assert "RETRACTING" in states, decisions
    assert "DONE" in states, decisions
    stop = decisions[1]
    assert stop[2] == "STOP", stop
    assert stop[3].startswith("contact: |F|="), stop
    assert decisions[states.index("DONE")][2] == "PUBLISH"
    assert all(d[3].strip() for d in decisions)

    # the window is cut from the behaviour's motion start, and the sensor's trial started moving
    # then too
    # (not subscribed to /extsense/motion_start here: the behaviour's auto start waits for its
    # two subscribers, the window node and the simulated sensor, and a third would fool it)
    motion_ns = decisions[0][0]  # the LOWERING decision is stamped with the motion start
    truth = recorder.got["/extsense/ground_truth"][0][1]
    assert _stamp(truth) == motion_ns
    assert truth.class_label == "apple"
    finals = [m for _, m in recorder.got["/extsense/contact_window"] if m.post_onset_ns >= 6e9]
    assert finals
    assert all(_stamp(w) == motion_ns for w in finals)
    result = recorder.got["/food/result"][0][1]
    assert _stamp(result) == motion_ns
    assert not result.provisional
    assert result.class_label in result.class_names

    # the fork came down at 1 cm/s and stopped on the first state sample with |F| >= 10 N,
    # then held still until the retract
    arm = [
        (_stamp(m), m.position[0], m.velocity[0], m.effort[0])
        for _, m in recorder.got["/arm/state"]
    ]
    lowering = [a for a in arm if a[0] < stop[0]]
    assert lowering
    # the descent is a FollowJointTrajectory of joint waypoints 50 ms apart (the sim_arm stands
    # in for franka_ros2's joint_trajectory_controller), interpolated linearly in joint space:
    # the Cartesian speed is 1 cm/s to within 0.16 % (measured), no longer exactly
    # the goal reaches the arm a moment after the decision (an action round trip, as on the
    # robot): from the first sample that moves, every one comes down at 1 cm/s
    moving = next(i for i, a in enumerate(lowering) if a[2] != 0.0)
    # moving within 3 s of the decision (an action round trip and the first 50 ms waypoint; on
    # slow 2-core machines running the whole suite 0.64 s once, and 1.79 s once, while the
    # simulated device computed the trial the motion start triggered)
    assert lowering[moving][0] - motion_ns < 3_000_000_000
    speeds = [v for _, _, v, _ in lowering[moving + 1 :]]
    assert speeds
    assert all(v == pytest.approx(-0.01, rel=2e-3) for v in speeds), speeds
    first_over = next(a for a in arm if a[3] >= 10.0)
    assert first_over[0] == stop[0]
    retract = next(d for d in decisions if d[1] == "RETRACTING")
    held = [a for a in arm if stop[0] < a[0] < retract[0]]
    assert held
    # the stop is a cancel of the trajectory goal over ROS (as on the robot): the fork travels on
    # until the arm takes it, 0.1 mm per 10 ms at 1 cm/s (0.11 mm seen under load), then holds
    assert max(abs(a[1] - first_over[1]) for a in held) < 1e-3
    still = held[len(held) // 2 :]
    assert max(a[1] for a in still) - min(a[1] for a in still) < 1e-6
    assert 0.129 < first_over[1] < 0.134  # 8 mm gap + 10 N / 500 N/m, force bias aside
    finished = next(d for d in decisions if d[1] == "DONE")
    retracted = [a for a in arm if a[0] <= finished[0]][-1]  # (a next probe may have begun since)
    assert retracted[1] == pytest.approx(0.16, abs=1e-3)  # back at the start height
