"""Carrying out the food machine's decisions on an arm, outside ROS.

:class:`FoodProbe` joins a :class:`~ext_sense_behaviours.food.FoodMachine` to an
:class:`~ext_sense_behaviours.arm.ArmAdapter`. The ``food_behaviour`` node uses it from its
timers and callbacks; scenario tests drive it in plain loops.
"""

from __future__ import annotations

from collections.abc import Callable

from ext_sense_behaviours.arm import ArmAdapter
from ext_sense_behaviours.decisions import Decision
from ext_sense_behaviours.errors import BehaviourError
from ext_sense_behaviours.food import FoodAction, FoodMachine, FoodResult
from ext_sense_behaviours.records import ArmState
from ext_sense_runtime.records import Estimate


class FoodProbe:
    """Runs one food probe on an arm.

    Calls back with the motion start (ns, as lowering begins), the complete window ``(start_ns,
    end_ns)``, the result once retracted, and every arm state read while probing.
    """

    def __init__(
        self,
        machine: FoodMachine,
        arm: ArmAdapter,
        on_motion_start: Callable[[int], None] | None = None,
        on_request: Callable[[int, int], None] | None = None,
        on_publish: Callable[[FoodResult], None] | None = None,
        on_state: Callable[[ArmState], None] | None = None,
    ) -> None:
        self.machine, self.arm = machine, arm
        self.on_motion_start = on_motion_start
        self.on_request = on_request
        self.on_publish = on_publish
        self.on_state = on_state
        self.samples = 0

    def start(self, now_ns: int | None = None) -> Decision | None:
        """Start from the arm's current state; ``None`` when the arm has no state yet.

        ``now_ns`` is the clock :meth:`step` gets (default: the state's own stamp).
        """
        state = self.arm.read_state()
        if state is None:
            return None
        return self._act(self.machine.start(state, now_ns))

    def step(self, now_ns: int) -> list[Decision]:
        """One control tick: feed the machine the arm's failure, one state and the clock.

        Carries out what the machine decides on each.
        """
        out = []
        failure = self.arm.take_failure()
        if failure is not None:
            out.append(self._act(self.machine.on_arm_failure(failure, now_ns)))
        state = self.arm.read_state()
        if state is not None:
            self.samples += 1
            if self.on_state is not None:
                self.on_state(state)
            decision = self.machine.on_arm_state(state, now_ns)
            if decision is not None:
                out.append(self._act(decision))
        decision = self.machine.on_tick(now_ns)
        if decision is not None:
            out.append(self._act(decision))
        return out

    def deliver(self, estimate: Estimate, now_ns: int) -> Decision | None:
        """Hand a food estimate to the machine."""
        decision = self.machine.on_estimate(estimate, now_ns)
        return None if decision is None else self._act(decision)

    def _act(self, decision: Decision) -> Decision:
        try:
            self._carry_out(decision)
        except BehaviourError as err:  # no robot state or no controller: the motion failed
            return self._act(self.machine.on_arm_failure(str(err), decision.stamp_ns))
        return decision

    def _carry_out(self, decision: Decision) -> None:
        cfg, m = self.machine.config, self.machine
        action = FoodAction[decision.action]
        if action == FoodAction.MOVE_DOWN:
            self.arm.move_down(cfg.speed_mps)
            if self.on_motion_start is not None:
                self.on_motion_start(m.motion_start_ns)
        elif action == FoodAction.STOP:
            self.arm.stop()
        elif action == FoodAction.REQUEST_CLASSIFICATION:
            if self.on_request is not None:
                self.on_request(m.motion_start_ns, m.motion_start_ns + cfg.window_end_ns)
        elif action == FoodAction.RETRACT:
            self.arm.retract(m.retract_height_m, cfg.retract_speed_mps)
        elif action == FoodAction.PUBLISH and self.on_publish is not None and m.result is not None:
            self.on_publish(m.result)
