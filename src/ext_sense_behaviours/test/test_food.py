"""Food behaviour on the simulated arm: lower at 1 cm/s, stop on 10 N or preset height,
collect the window, classify, retract, publish."""

from __future__ import annotations

import math

import pytest

from ext_sense_behaviours.arm import SimulatedArm
from ext_sense_behaviours.contact import ForceContactDetector
from ext_sense_behaviours.errors import BehaviourError
from ext_sense_behaviours.execution import FoodProbe
from ext_sense_behaviours.food import FoodConfig, FoodMachine, FoodResult, FoodState, StopReason
from ext_sense_behaviours.records import ArmState
from ext_sense_runtime.records import Estimate
from ext_sense_runtime.stamps import MS

STEP_NS = 10 * MS  # control period of the scenario (100 Hz)


class Clock:
    def __init__(self) -> None:
        self.ns = 1_000_000_000

    def __call__(self) -> int:
        return self.ns


def run_probe(surface_z_m, stiffness=1000.0, label="apple", answer=True, config=None):
    """One probe end to end: simulated arm, food machine, and a classifier stand-in that
    answers the window request with an estimate stamped at the motion start."""
    clock = Clock()
    arm = SimulatedArm(
        start_z_m=0.16, surface_z_m=surface_z_m, stiffness_n_per_m=stiffness, clock_ns=clock
    )
    config = config or FoodConfig(
        stop_height_m=0.103, window_end_ns=3000 * MS, classify_timeout_ns=1000 * MS
    )
    machine = FoodMachine(config)
    events = {"motion_start": [], "requests": [], "published": []}
    probe = FoodProbe(
        machine,
        arm,
        events["motion_start"].append,
        lambda a, b: events["requests"].append((a, b)),
        events["published"].append,
    )
    probe.start()
    trace = []
    for _ in range(3000):
        clock.ns += STEP_NS
        probe.step(clock.ns)
        trace.append((clock.ns, arm.z_m, arm.contact_force_n(), machine.state))
        if events["requests"] and answer and machine.state == FoodState.CLASSIFYING:
            start, _ = events["requests"][0]
            probe.deliver(Estimate("food_identification", start, class_label=label), clock.ns)
        if machine.state in (FoodState.DONE, FoodState.FAULT):
            break
    return machine, arm, events, trace


def test_fork_stops_on_contact_and_publishes_the_class():
    machine, arm, events, trace = run_probe(surface_z_m=0.12, stiffness=1000.0)
    assert machine.state == FoodState.DONE
    result: FoodResult = events["published"][0]
    assert result.stop_reason == StopReason.CONTACT
    assert result.estimate.class_label == "apple"
    assert result.stop_force_n >= 10.0
    # 10 N at 1000 N/m is 1 cm into the food; the simulated force estimate has a -0.5 N bias
    # on z (so about 10.5 N of contact), 0.05 N noise, and one 10 ms step at 1 cm/s adds 0.1 mm.
    depth = 0.12 - result.stop_z_m
    assert 0.0098 <= depth <= 0.0108, depth
    # lowering ran at 1 cm/s: from 0.16 to the stop took (0.16 - z) / 0.01 seconds
    lowering_s = (result.stop_ns - result.motion_start_ns) / 1e9
    assert lowering_s == pytest.approx((0.16 - result.stop_z_m) / 0.01, abs=0.02)
    # after the stop the fork did not go deeper until the retract
    stopped = [z for t, z, f, s in trace if s in (FoodState.COLLECTING, FoodState.CLASSIFYING)]
    assert max(stopped) - min(stopped) < 1e-9
    # retracted to where it started, then published
    assert arm.z_m == pytest.approx(0.16, abs=1e-4)
    assert [c.split()[0] for _, c in arm.commands] == ["move_down", "stop", "retract"]
    assert events["motion_start"] == [result.motion_start_ns]
    assert events["requests"] == [(result.motion_start_ns, result.motion_start_ns + 3000 * MS)]
    names = [d.state for d in machine.log.entries]
    assert names == ["LOWERING", "COLLECTING", "CLASSIFYING", "RETRACTING", "DONE"]


def test_no_food_stops_at_the_preset_height():
    machine, _arm, events, _ = run_probe(surface_z_m=None, label="empty")
    result = events["published"][0]
    assert result.stop_reason == StopReason.PRESET_HEIGHT
    assert 0.103 - 0.0001 <= result.stop_z_m <= 0.103
    assert "preset height" in machine.log.entries[1].reason


def test_soft_food_reaches_preset_height_before_10_n():
    # water/tofu in the real bags: |F| stayed near 4-5 N and the arm stopped at the preset height
    _machine, _, events, _ = run_probe(surface_z_m=0.12, stiffness=150.0, label="tofu")
    assert events["published"][0].stop_reason == StopReason.PRESET_HEIGHT


def test_missing_classification_times_out_and_still_retracts():
    machine, arm, events, _ = run_probe(surface_z_m=0.12, answer=False)
    assert machine.state == FoodState.DONE
    assert events["published"] == []
    assert machine.result.estimate is None
    assert "no food estimate within 1.0 s" in machine.log.entries[3].reason
    assert arm.z_m == pytest.approx(0.16, abs=1e-4)


def test_foreign_and_provisional_estimates_are_not_taken():
    clock = Clock()
    machine = FoodMachine(FoodConfig(window_end_ns=100 * MS))
    machine.start(ArmState(clock.ns, 0.16, (0.0, 0.0, 0.0)))
    machine.on_arm_state(ArmState(clock.ns + MS, 0.15, (0.0, 0.0, 12.0)))
    machine.on_tick(clock.ns + 200 * MS)
    assert machine.state == FoodState.CLASSIFYING
    d = machine.on_estimate(
        Estimate("food_identification", clock.ns + 5_000 * MS, class_label="x"), 0
    )
    assert "not this probe's motion start" in d.reason
    d = machine.on_estimate(
        Estimate("food_identification", clock.ns, provisional=True, class_label="x"), 0
    )
    assert "provisional" in d.reason
    assert machine.state == FoodState.CLASSIFYING
    d = machine.on_estimate(Estimate("tap_localization", clock.ns), 0)
    assert "task 'tap_localization'" in d.reason
    d = machine.on_estimate(Estimate("food_identification", clock.ns, class_label="tofu"), 0)
    assert d.action == "RETRACT"


def test_invalid_force_stops_the_arm():
    machine = FoodMachine(FoodConfig(invalid_force_limit=2))
    machine.start(ArmState(0, 0.16, (0.0, 0.0, 0.0)))
    assert machine.on_arm_state(ArmState(1, 0.15, (math.nan, 0.0, 0.0))) is None
    d = machine.on_arm_state(ArmState(2, 0.15, (0.0, math.nan, 0.0)))
    assert d.action == "STOP"
    assert d.state == "FAULT"
    assert "invalid force" in d.reason
    assert machine.detector.invalid_samples == 2


def test_lowering_timeout_stops_the_arm():
    machine = FoodMachine(FoodConfig(max_lowering_ns=1000 * MS, stop_height_m=0.0))
    machine.start(ArmState(0, 0.16, (0.0, 0.0, 0.0)))
    d = machine.on_arm_state(ArmState(1000 * MS, 0.15, (0.0, 0.0, 1.0)))
    assert d.action == "STOP"
    assert d.state == "FAULT"
    assert "within 1.0 s" in d.reason


def test_an_arm_state_stall_while_lowering_stops_and_holds():
    machine = FoodMachine(FoodConfig(state_timeout_ns=500 * MS))
    machine.start(ArmState(0, 0.16, (0.0, 0.0, 0.0)), now_ns=7 * MS)
    assert machine.on_arm_state(ArmState(10 * MS, 0.159, (0.0, 0.0, 0.0)), now_ns=17 * MS) is None
    assert machine.on_tick(516 * MS) is None
    d = machine.on_tick(517 * MS)
    assert (d.state, d.action) == ("FAULT", "STOP")
    assert "no arm state for 0.50 s while lowering" in d.reason
    assert machine.stop_reason == StopReason.ARM_FAULT


class StuckRetract(SimulatedArm):
    """Reaches the food but never goes back up; reports its own failure when ``reason`` is set."""

    def __init__(self, reason: str | None = None, **kwargs) -> None:
        super().__init__(**kwargs)
        self.reason, self._failure = reason, None

    def retract(self, height_m: float, speed_mps: float) -> None:
        self.stop()
        self._failure = self.reason

    def take_failure(self) -> str | None:
        failure, self._failure = self._failure, None
        return failure


def _probe_on(arm, clock, config):
    machine = FoodMachine(config)
    requests = []
    probe = FoodProbe(machine, arm, on_request=lambda a, b: requests.append(a))
    probe.start(clock.ns)
    for _ in range(3000):
        clock.ns += STEP_NS
        probe.step(clock.ns)
        if requests and machine.state == FoodState.CLASSIFYING:
            probe.deliver(Estimate("food_identification", requests[0], class_label="x"), clock.ns)
        if machine.state in (FoodState.DONE, FoodState.FAULT):
            break
    return machine


def test_a_retract_that_never_arrives_stops_and_holds_after_its_time_limit():
    clock = Clock()
    arm = StuckRetract(start_z_m=0.16, surface_z_m=0.14, clock_ns=clock)
    config = FoodConfig(window_end_ns=3000 * MS, max_retract_ns=2000 * MS)
    machine = _probe_on(arm, clock, config)
    assert machine.state == FoodState.FAULT
    assert "2.0 s after the retract's planned end: stop, hold" in machine.log.entries[-1].reason
    retract, fault = machine.log.entries[-2:]
    assert retract.action == "RETRACT"
    # planned: from where the fork stopped back to the start height at 5 cm/s
    planned_ns = (0.16 - machine.result.stop_z_m) / config.retract_speed_mps * 1e9
    assert 0 <= fault.stamp_ns - retract.stamp_ns - (planned_ns + 2000 * MS) < STEP_NS
    assert machine.result.estimate.class_label == "x"  # what it found is kept


def test_a_slow_retract_is_given_its_planned_time():
    config = FoodConfig(
        stop_height_m=0.103,
        window_end_ns=3000 * MS,
        retract_speed_mps=0.004,  # 4 cm back up at 4 mm/s: 10 s, against a 1 s margin
        max_retract_ns=1000 * MS,
    )
    machine, arm, _events, _trace = run_probe(0.12, config=config)
    assert machine.state == FoodState.DONE
    assert arm.z_m == pytest.approx(0.16, abs=1e-4)


def test_the_arm_s_motion_failure_stops_and_holds_at_once():
    clock = Clock()
    arm = StuckRetract(
        "trajectory goal rejected by the controller",
        start_z_m=0.16,
        surface_z_m=0.14,
        clock_ns=clock,
    )
    machine = _probe_on(arm, clock, FoodConfig(window_end_ns=3000 * MS))
    retract, fault = machine.log.entries[-2:]
    assert (fault.state, fault.action) == ("FAULT", "STOP")
    assert fault.reason == (
        "arm failure while retracting: trajectory goal rejected by the controller: stop, hold"
    )
    assert fault.stamp_ns - retract.stamp_ns == STEP_NS  # on the next control tick


def test_a_motion_command_the_arm_refuses_is_a_fault_not_a_crash():
    class NoController(SimulatedArm):
        def move_down(self, speed_mps: float) -> None:
            raise BehaviourError("trajectory action 'x' not available")

    clock = Clock()
    machine = FoodMachine()
    probe = FoodProbe(machine, NoController(clock_ns=clock))
    d = probe.start(clock.ns)
    assert (d.state, d.action) == ("FAULT", "STOP")
    assert "arm failure while lowering: trajectory action 'x' not available" in d.reason


def test_an_arm_failure_while_the_arm_holds_is_only_logged():
    machine = FoodMachine(FoodConfig(window_end_ns=100 * MS))
    machine.start(ArmState(0, 0.16, (0.0, 0.0, 0.0)))
    machine.on_arm_state(ArmState(MS, 0.15, (0.0, 0.0, 12.0)))
    assert machine.state == FoodState.COLLECTING
    d = machine.on_arm_failure("trajectory goal ended with status 6", 2 * MS)
    assert (d.state, d.action) == ("COLLECTING", "NONE")
    assert machine.state == FoodState.COLLECTING


def test_detector_consecutive_and_validation():
    det = ForceContactDetector(10.0, consecutive=2)
    assert [det.update(f) for f in (11.0, 5.0, 11.0, 12.0, 13.0)] == [
        False,
        False,
        False,
        True,
        False,
    ]
    assert det.fired_at == 3
    with pytest.raises(BehaviourError, match="'threshold_n' parameter"):
        ForceContactDetector(0.0)
    with pytest.raises(BehaviourError, match="'consecutive' parameter"):
        ForceContactDetector(10.0, 0)


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"speed_mps": 0.0}, "'speed_mps'"),
        ({"window_end_ns": 0}, "'window_end_ns'"),
        ({"invalid_force_limit": 0}, "'invalid_force_limit'"),
    ],
)
def test_food_config_checked(kwargs, match):
    with pytest.raises(BehaviourError, match=match):
        FoodConfig(**kwargs)


def test_simulated_arm_checks_speed():
    arm = SimulatedArm()
    with pytest.raises(BehaviourError, match="'speed_mps' argument must be > 0"):
        arm.move_down(0.0)
