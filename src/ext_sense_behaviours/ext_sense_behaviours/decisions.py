"""The decision log every behaviour keeps: what it did, when, and why."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from enum import IntEnum


@dataclass(frozen=True)
class Decision:
    """One decision: the state after it, the caller's action (``"NONE"``: nothing), and why."""

    stamp_ns: int
    state: str
    action: str
    reason: str

    def __str__(self) -> str:
        return f"[{self.stamp_ns}] {self.state}: {self.action} - {self.reason}"


@dataclass
class DecisionLog:
    """Keeps the last ``max_entries`` decisions (a node runs for days); a sink sees every one."""

    sink: Callable[[Decision], None] | None = None
    entries: list[Decision] = field(default_factory=list)
    max_entries: int = 10_000

    def record(self, stamp_ns: int, state: IntEnum, action: IntEnum, reason: str) -> Decision:
        """Append a decision and pass it to the sink."""
        decision = Decision(int(stamp_ns), state.name, action.name, reason)
        self.entries.append(decision)
        if len(self.entries) > self.max_entries:
            del self.entries[: len(self.entries) - self.max_entries]
        if self.sink is not None:
            self.sink(decision)
        return decision
