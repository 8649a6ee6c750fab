"""Food probing: lower the fork until contact or a preset height, collect, classify, retract.

States::

    IDLE --start--> LOWERING --|F| >= 10 N, or z <= preset height--> COLLECTING
    COLLECTING --window complete (motion start + window_end)--> CLASSIFYING
    CLASSIFYING --food estimate for this motion start (or timeout)--> RETRACTING
    RETRACTING --back at the retract height--> DONE (publish)
    any moving state --invalid force samples / lowering or retract timeout / arm state
        stalled / motion failed--> FAULT (stop, hold)

The window is defined from the start of the motion (the paper: 2 s to 8 s after it), so the
behaviour announces the motion start (the node publishes it on ``motion_start`` for the
``contact_window`` node) and waits until the window is complete before asking for the class.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from enum import IntEnum
from typing import NamedTuple

from ext_sense_behaviours.contact import ForceContactDetector
from ext_sense_behaviours.decisions import Decision, DecisionLog
from ext_sense_behaviours.errors import BehaviourError
from ext_sense_behaviours.records import ArmState
from ext_sense_runtime.records import Estimate

FOOD_TASK = "food_identification"


class FoodState(IntEnum):
    """Where the probing is."""

    IDLE = 0
    LOWERING = 1
    COLLECTING = 2
    CLASSIFYING = 3
    RETRACTING = 4
    DONE = 5
    FAULT = 6


class FoodAction(IntEnum):
    """What the caller must do after a decision."""

    NONE = 0
    MOVE_DOWN = 1
    """Start lowering at ``config.speed_mps`` and announce the motion start."""
    STOP = 2
    REQUEST_CLASSIFICATION = 3
    """The window is complete: classify it (or wait for the perception graph's estimate)."""
    RETRACT = 4
    PUBLISH = 5


class StopReason(IntEnum):
    """Why the fork stopped going down."""

    CONTACT = 1
    PRESET_HEIGHT = 2
    TIMEOUT = 3
    INVALID_FORCE = 4
    ARM_FAULT = 5
    """The arm's state stopped coming, or its motion failed (rejected, unanswered, aborted)."""


_NO_STOP = (0, StopReason.TIMEOUT, math.nan, math.nan, -1)
"""What a result records when the fork never stopped: (stop ns, reason, z, force, sample)."""


@dataclass(frozen=True)
class FoodConfig:
    """Parameters of the probing, as ``food_behaviour``'s (durations in ns).

    The paper lowers at 0.01 m/s and stops at 10 N. Without arm states (30 Hz to 1 kHz) the
    behaviour sees neither contact nor height: ``state_timeout_ns``. ``retract_height_m`` NaN:
    where the motion started. An estimate belongs to the probe within ``stamp_tolerance_ns`` of
    its motion start; ``invalid_force_limit`` NaN force samples in a row stop the arm (fault).
    """

    speed_mps: float = 0.01
    contact_threshold_n: float = 10.0
    contact_consecutive: int = 1
    stop_height_m: float = 0.103
    window_end_ns: int = 8_000_000_000
    classify_timeout_ns: int = 5_000_000_000
    max_lowering_ns: int = 15_000_000_000
    max_retract_ns: int = 10_000_000_000
    state_timeout_ns: int = 500_000_000
    retract_height_m: float = math.nan
    retract_speed_mps: float = 0.05
    accept_provisional: bool = False
    stamp_tolerance_ns: int = 100_000_000
    invalid_force_limit: int = 3

    def __post_init__(self) -> None:
        for name in (
            "speed_mps",
            "contact_threshold_n",
            "retract_speed_mps",
            "window_end_ns",
            "classify_timeout_ns",
            "max_lowering_ns",
            "max_retract_ns",
            "state_timeout_ns",
        ):
            value = getattr(self, name)
            if not (value > 0 and math.isfinite(value)):
                raise BehaviourError(f"The '{name}' parameter must be > 0. Got {value!r} instead.")
        if self.invalid_force_limit < 1:
            raise BehaviourError(
                f"The 'invalid_force_limit' parameter must be >= 1. Got "
                f"{self.invalid_force_limit!r} instead."
            )


class FoodResult(NamedTuple):
    """What one probe found: where and why lowering stopped, and the estimate (or ``None``).

    ``motion_start_ns`` is the window's onset; ``contact_sample`` the index of the arm state that
    declared contact (-1: none).
    """

    motion_start_ns: int
    stop_ns: int
    stop_reason: StopReason
    stop_z_m: float
    stop_force_n: float
    contact_sample: int
    estimate: Estimate | None


class FoodMachine:
    """The food-probing state machine; feed it events, act on its decisions (``sink`` too)."""

    def __init__(
        self, config: FoodConfig | None = None, sink: Callable[[Decision], None] | None = None
    ) -> None:
        self.config = config or FoodConfig()
        self.log = DecisionLog(sink)
        self.state = FoodState.IDLE
        self.detector = ForceContactDetector(
            self.config.contact_threshold_n, self.config.contact_consecutive
        )
        self.motion_start_ns = 0
        self.retract_height_m = math.nan
        self.result: FoodResult | None = None
        self.stop_reason: StopReason | None = None
        self._stop: tuple[int, StopReason, float, float, int] | None = None
        self._window_done_ns = 0
        self._retract_due_ns = 0  # when the retract must be done by, caller's clock
        self._state_ns = 0  # when the newest arm state was read, caller's clock

    def _decide(self, now_ns: int, state: FoodState, action: FoodAction, reason: str) -> Decision:
        self.state = state
        return self.log.record(now_ns, state, action, reason)

    def _note(self, now_ns: int, reason: str) -> Decision:
        return self.log.record(now_ns, self.state, FoodAction.NONE, reason)

    def start(self, arm: ArmState, now_ns: int | None = None) -> Decision:
        """Begin a probe from the arm's current state: lower the fork.

        ``now_ns`` is when the state was read on the clock :meth:`on_tick` gets (default: the
        state's stamp); the arm-state stall check counts from it.
        """
        if self.state not in (FoodState.IDLE, FoodState.DONE):
            return self._note(arm.stamp_ns, f"start ignored in {self.state.name}")
        cfg = self.config
        self.detector = ForceContactDetector(cfg.contact_threshold_n, cfg.contact_consecutive)
        self.motion_start_ns = arm.stamp_ns
        self.retract_height_m = (
            arm.z_m if math.isnan(cfg.retract_height_m) else cfg.retract_height_m
        )
        self.result, self._stop, self.stop_reason = None, None, None
        self._state_ns = arm.stamp_ns if now_ns is None else now_ns
        return self._decide(
            arm.stamp_ns,
            FoodState.LOWERING,
            FoodAction.MOVE_DOWN,
            f"lowering from z={arm.z_m:.4f} m at {cfg.speed_mps * 100:.1f} cm/s until "
            f"|F| >= {cfg.contact_threshold_n:.1f} N or z <= {cfg.stop_height_m:.4f} m",
        )

    def _halt(self, arm: ArmState, reason: StopReason, state: FoodState, text: str) -> Decision:
        index = self.detector.samples - 1
        self._stop = (arm.stamp_ns, reason, arm.z_m, arm.force_norm_n, index)
        self.stop_reason = reason
        return self._decide(arm.stamp_ns, state, FoodAction.STOP, text)

    def on_arm_state(self, arm: ArmState, now_ns: int | None = None) -> Decision | None:
        """Feed one arm state sample (every one, in order), read at ``now_ns`` (see ``start``)."""
        cfg = self.config
        self._state_ns = arm.stamp_ns if now_ns is None else now_ns
        if self.state == FoodState.LOWERING:
            norm = arm.force_norm_n
            if self.detector.update(norm):
                return self._halt(
                    arm,
                    StopReason.CONTACT,
                    FoodState.COLLECTING,
                    f"contact: |F|={norm:.2f} N >= {cfg.contact_threshold_n:.1f} N at "
                    f"z={arm.z_m:.4f} m (state sample {self.detector.fired_at}): stop",
                )
            if self.detector.invalid_run >= cfg.invalid_force_limit:
                return self._halt(
                    arm,
                    StopReason.INVALID_FORCE,
                    FoodState.FAULT,
                    f"{self.detector.invalid_run} invalid force samples in a row: stop, hold",
                )
            if arm.z_m <= cfg.stop_height_m:
                return self._halt(
                    arm,
                    StopReason.PRESET_HEIGHT,
                    FoodState.COLLECTING,
                    f"preset height: z={arm.z_m:.4f} m <= {cfg.stop_height_m:.4f} m without "
                    f"contact (|F|={norm:.2f} N): stop",
                )
            if arm.stamp_ns - self.motion_start_ns >= cfg.max_lowering_ns:
                return self._halt(
                    arm,
                    StopReason.TIMEOUT,
                    FoodState.FAULT,
                    f"no contact nor preset height within {cfg.max_lowering_ns / 1e9:.1f} s: "
                    "stop, hold",
                )
            return None
        if self.state == FoodState.RETRACTING and arm.z_m >= self.retract_height_m - 1e-4:
            return self._finish(arm.stamp_ns)
        return None

    def on_arm_failure(self, reason: str, now_ns: int) -> Decision:
        """The arm's motion failed (the adapter's report): a moving probe stops and holds."""
        if self.state not in (FoodState.LOWERING, FoodState.RETRACTING):
            return self._note(now_ns, f"arm failure while not moving: {reason}")
        return self._fault(now_ns, f"arm failure while {self.state.name.lower()}: {reason}")

    def _fault(self, now_ns: int, text: str) -> Decision:
        """Stop and hold for a reason of the arm, not of the force (no state sample to quote)."""
        if self.state == FoodState.LOWERING:
            self._stop = (now_ns, StopReason.ARM_FAULT, math.nan, math.nan, -1)
            self.stop_reason = StopReason.ARM_FAULT
        return self._decide(now_ns, FoodState.FAULT, FoodAction.STOP, f"{text}: stop, hold")

    def on_tick(self, now_ns: int) -> Decision | None:
        """Check the window end, the timeouts and the arm state's flow; call periodically."""
        cfg = self.config
        if (
            self.state in (FoodState.LOWERING, FoodState.RETRACTING)
            and now_ns - self._state_ns >= cfg.state_timeout_ns
        ):
            return self._fault(
                now_ns,
                f"no arm state for {(now_ns - self._state_ns) / 1e9:.2f} s while "
                f"{self.state.name.lower()}",
            )
        if self.state == FoodState.RETRACTING and now_ns >= self._retract_due_ns:
            return self._fault(
                now_ns,
                f"not back at z={self.retract_height_m:.4f} m "
                f"{cfg.max_retract_ns / 1e9:.1f} s after the retract's planned end",
            )
        if (
            self.state == FoodState.COLLECTING
            and now_ns >= self.motion_start_ns + cfg.window_end_ns
        ):
            self._window_done_ns = now_ns
            return self._decide(
                now_ns,
                FoodState.CLASSIFYING,
                FoodAction.REQUEST_CLASSIFICATION,
                f"window complete ({cfg.window_end_ns / 1e9:.1f} s after motion start): classify",
            )
        if (
            self.state == FoodState.CLASSIFYING
            and now_ns - self._window_done_ns >= cfg.classify_timeout_ns
        ):
            return self._retract(
                now_ns,
                None,
                f"no food estimate within {cfg.classify_timeout_ns / 1e9:.1f} s: retract "
                "without a class",
            )
        return None

    def on_estimate(self, estimate: Estimate, now_ns: int) -> Decision | None:
        """Take the food estimate for this probe; anything else is logged and ignored."""
        cfg = self.config
        if self.state not in (FoodState.COLLECTING, FoodState.CLASSIFYING):
            return None
        if estimate.task != FOOD_TASK:
            return self._note(
                now_ns, f"estimate ignored: task '{estimate.task}', expected '{FOOD_TASK}'"
            )
        if abs(estimate.onset_ns - self.motion_start_ns) > cfg.stamp_tolerance_ns:
            return self._note(
                now_ns,
                f"estimate ignored: stamp {estimate.onset_ns} is not this probe's motion start "
                f"{self.motion_start_ns}",
            )
        if estimate.provisional and not cfg.accept_provisional:
            return self._note(
                now_ns,
                f"provisional estimate '{estimate.class_label}' noted; waiting for the final one",
            )
        return self._retract(
            now_ns,
            estimate,
            f"classified as '{estimate.class_label}': retract to z={self.retract_height_m:.4f} m",
        )

    def _retract(self, now_ns: int, estimate: Estimate | None, text: str) -> Decision:
        """Store the result and retract, due by its planned duration plus ``max_retract_ns``.

        Planned from where the fork stopped to the retract height at ``retract_speed_mps``.
        """
        cfg = self.config
        stop_ns, reason, z, force, index = self._stop or _NO_STOP
        contact = index if reason == StopReason.CONTACT else -1
        self.result = FoodResult(self.motion_start_ns, stop_ns, reason, z, force, contact, estimate)
        distance = self.retract_height_m - z
        planned_ns = round(distance / cfg.retract_speed_mps * 1e9) if distance > 0 else 0
        self._retract_due_ns = now_ns + planned_ns + cfg.max_retract_ns
        return self._decide(now_ns, FoodState.RETRACTING, FoodAction.RETRACT, text)

    def _finish(self, now_ns: int) -> Decision:
        estimate = self.result.estimate if self.result is not None else None
        if estimate is None:
            return self._decide(
                now_ns, FoodState.DONE, FoodAction.NONE, "retracted: no class to publish"
            )
        text = f"retracted: publish '{estimate.class_label}'"
        return self._decide(now_ns, FoodState.DONE, FoodAction.PUBLISH, text)
