"""A handover run outside ROS: the handover machine joined to a Robotiq 2F (test helper).

:class:`HandoverRun` feeds estimates to a :class:`~ext_sense_behaviours.handover.HandoverMachine`
and carries out its decisions on a :class:`GripperPort`; :class:`RobotiqGripperPort` is one over
:class:`ext_sense_drivers.robotiq.RobotiqClient`. The scenario tests drive them in plain loops
against the emulated gripper; the ``handover_behaviour`` node does the same through the
``robotiq_gripper`` node's action.
"""

from __future__ import annotations

from typing import Protocol

from ext_sense_behaviours.decisions import Decision
from ext_sense_behaviours.gripper import describe_position, is_open, settled
from ext_sense_behaviours.handover import HandoverAction, HandoverMachine, HandoverState
from ext_sense_drivers.robotiq import GripperStatus, RobotiqClient, RobotiqError
from ext_sense_runtime.records import Estimate


class GripperPort(Protocol):
    """What the handover needs from a gripper; both methods raise on a fault."""

    def open(self) -> None:
        """Start opening the fingers."""

    def is_open(self) -> bool:
        """Whether the fingers have finished opening."""

    def read(self) -> GripperStatus:
        """The status as it is, gripper faults included (raises only when the link fails)."""


class RobotiqGripperPort:
    """A :class:`GripperPort` over a Robotiq client.

    Args:
        client: An activated client.
        speed, force: rSP and rFR used to open, 0..255.

    Raises on use:
        RobotiqError: The exchange failed or the gripper reports a fault; the caller must
            keep holding (the handover machine's FAULT state).
    """

    def __init__(self, client: RobotiqClient, speed: int = 128, force: int = 50) -> None:
        self.client = client
        self.speed, self.force = speed, force

    def open(self) -> None:
        """Send the open command."""
        self.client.open_fingers(self.speed, self.force)

    def is_open(self) -> bool:
        """Poll the status; True once the opening has ended near position 0."""
        return is_open(self.client.read_status(raise_on_fault=True))

    def read(self) -> GripperStatus:
        """One status read; a gripper fault is reported in the status, not raised."""
        return self.client.read_status()


class HandoverRun:
    """Runs one handover on a gripper; gripper errors put the machine in its safe state.

    Args:
        machine: The state machine.
        gripper: The gripper port (raises ``RobotiqError`` on faults and lost links).
    """

    def __init__(self, machine: HandoverMachine, gripper: GripperPort) -> None:
        self.machine, self.gripper = machine, gripper
        self.open_commands = 0

    def start(self, now_ns: int) -> Decision:
        """The object is held: start waiting."""
        return self.machine.start(now_ns)

    def estimate(self, estimate: Estimate, now_ns: int) -> Decision:
        """Feed one estimate; opens the gripper when the machine says so."""
        decision = self.machine.on_estimate(estimate, now_ns)
        if HandoverAction[decision.action] == HandoverAction.OPEN_GRIPPER:
            try:
                self.open_commands += 1
                self.gripper.open()
            except RobotiqError as err:
                return self.machine.on_fault(str(err), now_ns)
        return decision

    def tick(self, now_ns: int) -> Decision | None:
        """Poll the gripper while releasing, re-read it after a fault, check the timeouts."""
        if self.machine.state == HandoverState.FAULT and self.machine.awaiting_status:
            try:
                status = self.gripper.read()
            except RobotiqError:
                return None  # the link still fails: read again on the next tick
            return self.machine.on_status_after_fault(
                is_open(status), settled(status), describe_position(status), now_ns
            )
        if self.machine.state == HandoverState.RELEASING:
            try:
                opened = self.gripper.is_open()
            except RobotiqError as err:
                return self.machine.on_fault(str(err), now_ns)
            decision = self.machine.on_gripper(opened, now_ns)
            if decision is not None:
                return decision
        return self.machine.on_tick(now_ns)
