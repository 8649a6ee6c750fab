"""The franka_ros2 arm adapter against the simulated arm, over the real franka_ros2 interfaces.

The adapter is the code that runs on the robot; ``sim_arm`` serves FrankaRobotState,
SetFullCollisionBehavior, FollowJointTrajectory and ErrorRecovery under franka_ros2's names.
"""

from __future__ import annotations

import pytest

pytestmark = pytest.mark.ros

rclpy = pytest.importorskip("rclpy")
pytest.importorskip(
    "franka_msgs", reason="franka_msgs is not built into this venv: make setup builds interfaces/"
)

from control_msgs.action import FollowJointTrajectory  # noqa: E402
from rclpy.action import ActionClient  # noqa: E402
from rclpy.action.client import ClientGoalHandle  # noqa: E402
from rclpy.executors import SingleThreadedExecutor  # noqa: E402
from rclpy.parameter import Parameter  # noqa: E402
from rosutil import spin_until  # noqa: E402

from ext_sense_behaviours.errors import BehaviourError  # noqa: E402
from ext_sense_behaviours.nodes.franka_adapter import FrankaArmAdapter  # noqa: E402
from ext_sense_sim.nodes.sim_arm import SimArmNode  # noqa: E402


def _rig(sim_parameters: list[Parameter], **adapter_kwargs):
    """The simulated robot and the adapter, each on an executor of its own, spun on demand
    (``spin_until`` with both; a test leaves the robot's out to make it stop answering)."""
    context = rclpy.Context()
    rclpy.init(context=context)
    sim = SimArmNode(context=context, parameter_overrides=sim_parameters)
    host = rclpy.create_node("food_behaviour", context=context)
    adapter = FrankaArmAdapter(host, max_descent_m=0.05, **adapter_kwargs)
    executors = []
    for node in (sim, host):
        executor = SingleThreadedExecutor(context=context)
        executor.add_node(node)
        executors.append(executor)
    try:
        yield sim, adapter, executors
    finally:
        for executor in executors:
            executor.shutdown()
        adapter.destroy()
        sim.destroy_node()
        host.destroy_node()
        rclpy.try_shutdown(context=context)


@pytest.fixture
def rig():
    # reflex at 6 N, contact flag at 3 N: the robot's own flag stops the descent
    yield from _rig(
        [
            Parameter("start_z_m", value=0.16),
            Parameter("surface_z_m", value=0.152),
            Parameter("force_noise_n", value=0.0),
        ],
        collision_force_n=6.0,
    )


def test_adapter_reads_state_sets_thresholds_descends_and_stops_on_the_contact_flag(rig):
    sim, adapter, executors = rig
    # thresholds: the robot holds what the adapter asked for
    assert spin_until(executors, lambda: adapter.thresholds_set is not None)
    assert adapter.thresholds_set is True
    assert sim.arm.thresholds["upper_force_thresholds_nominal"] == [6.0] * 3 + [20.0] * 3
    assert sim.arm.thresholds["lower_force_thresholds_nominal"] == [3.0] * 3 + [10.0] * 3
    # state: height and the external force estimate (here the bias only)
    assert spin_until(executors, lambda: adapter.read_state() is not None)
    state = adapter.reading.state
    assert state.z_m == pytest.approx(0.16, abs=1e-5)
    assert state.force_n == pytest.approx((-0.5, 0.4, -0.5))
    # descent through FollowJointTrajectory at 1 cm/s
    assert spin_until(executors, lambda: adapter.trajectory_ready)
    adapter.move_down(0.01)
    assert spin_until(executors, lambda: adapter.reading.state.z_m < 0.157)
    assert adapter.reading.state.velocity_z_mps == pytest.approx(-0.01, rel=0.05)
    assert sim.goals["accepted"] == 1
    # the contact flag (|F_z| > 3 N, 3 mm into the 1000 N/m surface) stops it; no reflex
    assert spin_until(executors, lambda: adapter.counters["contact_stops"] == 1)
    assert spin_until(executors, lambda: sim.goals["canceled"] == 1)
    assert not sim.arm.reflex
    held = sim.arm.pose[2, 3]
    spin_until(executors, lambda: False, 0.5)
    assert sim.arm.pose[2, 3] == pytest.approx(held, abs=1e-9)  # holds where it stopped
    assert adapter.reading.state.z_m == pytest.approx(held, abs=1e-6)
    assert 0.152 - 0.0045 < held < 0.152 - 0.003
    assert 3.0 < adapter.reading.state.force_n[2] < 6.0
    # retract to the start height
    adapter.retract(0.16, 0.05)
    assert spin_until(executors, lambda: sim.goals["succeeded"] == 1)
    # the state message that shows the arm back up may arrive after the goal's result
    assert spin_until(executors, lambda: abs(adapter.reading.state.z_m - 0.16) <= 1e-4)
    assert adapter.counters["goals_failed"] == 0
    assert adapter.counters["goals_rejected"] == 0


def test_software_stop_before_the_flag_cancels_and_holds(rig):
    sim, adapter, executors = rig
    assert spin_until(executors, lambda: adapter.read_state() is not None)
    assert spin_until(executors, lambda: adapter.trajectory_ready)  # discovery takes a moment
    adapter.move_down(0.02)
    assert spin_until(executors, lambda: adapter.reading.state.z_m < 0.158)
    adapter.stop()  # the behaviour's own stop (e.g. its 10 N threshold, or the preset height)
    assert spin_until(executors, lambda: sim.goals["canceled"] == 1)
    held = sim.arm.pose[2, 3]
    spin_until(executors, lambda: False, 0.3)
    assert sim.arm.pose[2, 3] == pytest.approx(held, abs=1e-9)
    assert held > 0.152  # above the surface: never touched
    assert adapter.counters["contact_stops"] == 0


def test_adapter_without_robot_state_refuses_to_plan(rig):
    _sim, adapter, _executors = rig
    with pytest.raises(BehaviourError, match="no robot state yet"):
        adapter.move_down(0.01)


@pytest.fixture
def split_rig():
    yield from _rig(
        [Parameter("force_noise_n", value=0.0)], accept_timeout_s=0.5, result_margin_s=0.2
    )


def _ready(sim_ex, host_ex, adapter) -> None:
    assert spin_until([sim_ex, host_ex], lambda: adapter.reading is not None, 10.0)
    assert spin_until([sim_ex, host_ex], lambda: adapter.trajectory_ready, 10.0)


def test_a_goal_the_controller_does_not_answer_fails_once_and_a_late_acceptance_is_canceled(
    split_rig,
):
    sim, adapter, (sim_ex, host_ex) = split_rig
    _ready(sim_ex, host_ex, adapter)
    adapter.move_down(0.01)
    assert adapter.descending
    # the robot's executor is not spun: the goal response never comes
    assert spin_until([host_ex], lambda: adapter.counters["goals_unanswered"] == 1, 5.0)
    failure = adapter.take_failure()
    assert failure is not None
    assert "not answered within 0.5 s" in failure
    assert adapter.take_failure() is None  # reported once
    assert not adapter.descending
    # the robot answers late: the stale goal is canceled, nothing more is reported
    assert spin_until([sim_ex, host_ex], lambda: sim.goals["canceled"] == 1, 10.0)
    assert adapter.take_failure() is None
    assert adapter.counters["goals_failed"] == adapter.counters["goals_rejected"] == 0


def test_a_result_that_does_not_come_ends_the_motion_and_the_goal_is_canceled(split_rig):
    sim, adapter, (sim_ex, host_ex) = split_rig
    _ready(sim_ex, host_ex, adapter)
    adapter.move_down(0.1)  # 5 cm at 10 cm/s: planned 0.5 s, result due within 0.7 s
    assert spin_until([sim_ex, host_ex], lambda: sim.goals["accepted"] == 1, 5.0)
    # the robot stops answering: its result never comes
    assert spin_until([host_ex], lambda: adapter.counters["goals_timed_out"] == 1, 5.0)
    failure = adapter.take_failure()
    assert failure is not None
    assert "no result 0.2 s after its planned end" in failure
    # the robot resumes: the goal ends (canceled, or done before it read the cancel); ignored
    assert spin_until(
        [sim_ex, host_ex], lambda: sim.goals["canceled"] + sim.goals["succeeded"] == 1, 10.0
    )
    spin_until([sim_ex, host_ex], lambda: False, 0.3)
    assert adapter.take_failure() is None
    assert adapter.counters["goals_failed"] == 0


def test_a_rejected_goal_is_reported_as_the_motion_failure_until_the_next_motion(split_rig):
    sim, adapter, (sim_ex, host_ex) = split_rig
    _ready(sim_ex, host_ex, adapter)
    good = adapter.reading
    adapter.reading = good._replace(joint_names=("a", "b", "c", "d", "e", "f", "g"))
    adapter.move_down(0.01)
    assert spin_until([sim_ex, host_ex], lambda: adapter.counters["goals_rejected"] == 1, 5.0)
    assert sim.goals["rejected"] == 1
    adapter.reading = good
    adapter.retract(0.2, 0.05)  # the failure nobody took is old news for a new motion
    assert adapter.take_failure() is None
    adapter.reading = good._replace(joint_names=("a", "b", "c", "d", "e", "f", "g"))
    adapter.move_down(0.01)
    assert spin_until([sim_ex, host_ex], lambda: adapter.counters["goals_rejected"] == 2, 5.0)
    assert adapter.take_failure() == "trajectory goal rejected by the controller"


def test_a_goal_accepted_but_whose_answer_is_lost_is_canceled_by_its_id(split_rig):
    """The controller moves the arm; only its answer never reaches the adapter."""
    sim, adapter, (sim_ex, host_ex) = split_rig
    _ready(sim_ex, host_ex, adapter)
    adapter._on_goal_response = lambda *_args: None  # the goal response is lost on the way
    adapter.move_down(0.01)
    assert spin_until([sim_ex, host_ex], lambda: sim.goals["accepted"] == 1, 5.0)
    assert spin_until([sim_ex, host_ex], lambda: adapter.counters["goals_unanswered"] == 1, 5.0)
    assert spin_until([sim_ex, host_ex], lambda: sim.goals["canceled"] == 1, 5.0)
    held = sim.arm.pose[2, 3]
    spin_until([sim_ex, host_ex], lambda: False, 0.3)
    assert sim.arm.pose[2, 3] == pytest.approx(held, abs=1e-9)  # stopped, not descending on


def test_a_goal_canceled_by_someone_else_is_a_failure(split_rig):
    sim, adapter, (sim_ex, host_ex) = split_rig
    _ready(sim_ex, host_ex, adapter)
    adapter.move_down(0.01)
    assert spin_until([sim_ex, host_ex], lambda: adapter._goal is not None, 5.0)
    other = ActionClient(adapter.node, FollowJointTrajectory, adapter.names.trajectory_action)
    response = FollowJointTrajectory.Impl.SendGoalService.Response(accepted=True)
    ClientGoalHandle(other, adapter._goal.goal_id, response).cancel_goal_async()
    assert spin_until([sim_ex, host_ex], lambda: sim.goals["canceled"] == 1, 5.0)
    assert spin_until([sim_ex, host_ex], lambda: adapter.counters["goals_failed"] == 1, 5.0)
    assert adapter.take_failure() == "trajectory goal canceled by the controller"
    other.destroy()
