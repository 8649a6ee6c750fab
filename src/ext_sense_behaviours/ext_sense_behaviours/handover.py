"""Robot-to-human handover: release the object only once the person's grasp is stable.

States::

    IDLE --start--> HOLDING --N in a row P(stable) >= threshold--> RELEASING --open--> RELEASED
                      +--safety timeout--> TIMED_OUT (keep holding)
                      +--gripper fault / link lost--> FAULT (keep holding, stop commanding)
    RELEASING --release timeout--> FAULT
    FAULT --status read once the link answers--> RELEASED (the open command ran) or FAULT

The safe state is always "keep holding". A link error after the open command is ambiguous (the
fingers may be opening), so after a fault the machine waits for one status read
(:meth:`HandoverMachine.on_status_after_fault`). Provisional estimates count only with
``accept_provisional``; every estimate ignored or breaking the streak is logged with its reason.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from enum import IntEnum

from ext_sense_behaviours.decisions import Decision, DecisionLog
from ext_sense_behaviours.errors import BehaviourError
from ext_sense_runtime.records import Estimate

HANDOVER_TASK = "handover_stability"


class HandoverState(IntEnum):
    """Where the handover is."""

    IDLE = 0
    HOLDING = 1
    RELEASING = 2
    RELEASED = 3
    TIMED_OUT = 4
    FAULT = 5


class HandoverAction(IntEnum):
    """What the caller must do after a decision."""

    NONE = 0
    OPEN_GRIPPER = 1
    HOLD = 2
    """Keep the gripper closed and send it nothing more (safe state)."""


@dataclass(frozen=True)
class HandoverConfig:
    """Parameters of the handover decision (as ``handover_behaviour``'s, durations in ns)."""

    threshold: float = 0.8
    consecutive: int = 3
    accept_provisional: bool = False
    timeout_ns: int = 30_000_000_000
    release_timeout_ns: int = 3_000_000_000

    def __post_init__(self) -> None:
        if not 0.0 < self.threshold <= 1.0:
            raise BehaviourError(
                f"The 'threshold' parameter must be in (0, 1]. Got {self.threshold!r} instead."
            )
        if self.consecutive < 1:
            raise BehaviourError(
                f"The 'consecutive' parameter must be >= 1. Got {self.consecutive!r} instead."
            )
        for name in ("timeout_ns", "release_timeout_ns"):
            if getattr(self, name) <= 0:
                raise BehaviourError(
                    f"The '{name}' parameter must be > 0. Got {getattr(self, name)!r} instead."
                )


class HandoverMachine:
    """The handover state machine; feed it events, act on its decisions (``sink`` too)."""

    def __init__(
        self, config: HandoverConfig | None = None, sink: Callable[[Decision], None] | None = None
    ) -> None:
        self.config = config or HandoverConfig()
        self.log = DecisionLog(sink)
        self.state = HandoverState.IDLE
        self.streak = 0
        self._hold_since_ns = 0
        self._release_since_ns = 0
        self.awaiting_status = False
        """True after a fault until one gripper status read says where the fingers are."""
        self._open_sent = False

    def _decide(
        self, now_ns: int, state: HandoverState, action: HandoverAction, reason: str
    ) -> Decision:
        self.state = state
        return self.log.record(now_ns, state, action, reason)

    def _note(self, now_ns: int, reason: str) -> Decision:
        return self.log.record(now_ns, self.state, HandoverAction.NONE, reason)

    def start(self, now_ns: int) -> Decision:
        """The object is grasped and offered: start waiting for a stable human grasp."""
        if self.state not in (HandoverState.IDLE, HandoverState.RELEASED, HandoverState.TIMED_OUT):
            return self._note(now_ns, f"start ignored in state {self.state.name}")
        self.streak = 0
        self._hold_since_ns = now_ns
        self._open_sent = False
        return self._decide(
            now_ns,
            HandoverState.HOLDING,
            HandoverAction.HOLD,
            f"holding; open after {self.config.consecutive} consecutive estimates with "
            f"P(stable) >= {self.config.threshold:.2f}",
        )

    def on_estimate(self, estimate: Estimate, now_ns: int) -> Decision:
        """Count one stability estimate; returns OPEN_GRIPPER when the streak completes."""
        cfg = self.config
        if self.state != HandoverState.HOLDING:
            return self._note(now_ns, f"estimate ignored: not holding (state {self.state.name})")
        if estimate.task != HANDOVER_TASK:
            return self._note(
                now_ns, f"estimate ignored: task '{estimate.task}', expected '{HANDOVER_TASK}'"
            )
        p = float(estimate.stability_probability)
        if estimate.provisional and not cfg.accept_provisional:
            return self._note(
                now_ns,
                f"provisional estimate P(stable)={p:.3f} ignored (accept_provisional is false); "
                f"streak stays {self.streak}/{cfg.consecutive}",
            )
        if math.isnan(p) or not 0.0 <= p <= 1.0:
            self.streak = 0
            return self._note(
                now_ns, f"invalid P(stable)={p!r}: streak reset to 0/{cfg.consecutive}"
            )
        if p < cfg.threshold:
            self.streak = 0
            return self._note(
                now_ns,
                f"P(stable)={p:.3f} < {cfg.threshold:.2f}: unstable grasp, streak reset to "
                f"0/{cfg.consecutive}",
            )
        self.streak += 1
        if self.streak < cfg.consecutive:
            return self._note(
                now_ns,
                f"P(stable)={p:.3f} >= {cfg.threshold:.2f}: streak {self.streak}/{cfg.consecutive}",
            )
        self._release_since_ns = now_ns
        self._open_sent = True
        return self._decide(
            now_ns,
            HandoverState.RELEASING,
            HandoverAction.OPEN_GRIPPER,
            f"P(stable)={p:.3f} >= {cfg.threshold:.2f} for {self.streak} consecutive estimates"
            f"{' (provisional accepted)' if estimate.provisional else ''}: opening the gripper",
        )

    def on_gripper(self, opened: bool, now_ns: int) -> Decision | None:
        """Report whether the gripper has finished opening; completes a release."""
        if self.state == HandoverState.RELEASING and opened:
            return self._decide(
                now_ns,
                HandoverState.RELEASED,
                HandoverAction.NONE,
                "gripper reports open: released",
            )
        return None

    def on_fault(self, reason: str, now_ns: int) -> Decision:
        """The gripper or its link failed: keep holding, stop commanding, re-read the status.

        After the open command the outcome is unknown (the write may have been carried out):
        :meth:`on_status_after_fault` records the real finger state once the link answers.
        """
        if self.state in (HandoverState.RELEASED, HandoverState.FAULT):
            return self._note(now_ns, f"fault after the end: {reason}")
        self.awaiting_status = True
        if self._open_sent:
            text = (
                f"gripper error after the open command, outcome unknown (the fingers may be "
                f"opening); sending nothing more, re-reading the status: {reason}"
            )
        else:
            text = f"gripper fault, holding safe; re-reading the status: {reason}"
        return self._decide(now_ns, HandoverState.FAULT, HandoverAction.HOLD, text)

    def on_status_after_fault(
        self, opened: bool, settled: bool, description: str, now_ns: int
    ) -> Decision | None:
        """Record where the fingers really are after a fault, from a fresh status read.

        ``opened`` as ``gripper.is_open``; ``settled``: not moving (motion done, or stopped by a
        fault). ``None`` when no read is awaited or the fingers still move (read again); else
        RELEASED when the open command was carried out, or FAULT (held until an operator reset).
        """
        if self.state != HandoverState.FAULT or not self.awaiting_status:
            return None
        if opened and self._open_sent:
            self.awaiting_status = False
            return self._decide(
                now_ns,
                HandoverState.RELEASED,
                HandoverAction.NONE,
                f"link answers again: {description}; the open command was carried out: released",
            )
        if not settled:
            return None
        self.awaiting_status = False
        if opened:
            text = f"link answers again: {description}; fingers open without an open command"
        else:
            text = (
                f"link answers again: {description}; the object is still held, holding safe "
                "until an operator reset"
            )
        return self._decide(now_ns, HandoverState.FAULT, HandoverAction.HOLD, text)

    def reset(self, now_ns: int, reason: str = "operator reset") -> Decision:
        """Leave FAULT (or any state) for IDLE; only on an explicit request, never by itself."""
        self.streak = 0
        self.awaiting_status = False
        return self._decide(now_ns, HandoverState.IDLE, HandoverAction.NONE, reason)

    def on_tick(self, now_ns: int) -> Decision | None:
        """Check the timeouts; call periodically."""
        cfg = self.config
        if self.state == HandoverState.HOLDING and now_ns - self._hold_since_ns >= cfg.timeout_ns:
            return self._decide(
                now_ns,
                HandoverState.TIMED_OUT,
                HandoverAction.HOLD,
                f"no stable grasp within {cfg.timeout_ns / 1e9:.1f} s (streak "
                f"{self.streak}/{cfg.consecutive}): keep holding",
            )
        if (
            self.state == HandoverState.RELEASING
            and now_ns - self._release_since_ns >= cfg.release_timeout_ns
        ):
            return self._decide(
                now_ns,
                HandoverState.FAULT,
                HandoverAction.HOLD,
                f"gripper did not report open within {cfg.release_timeout_ns / 1e9:.1f} s",
            )
        return None
