"""An arm adapter that replays recorded states (the real Panda bags) and logs commands.

The recorded arm moved on its own, so commands change nothing: they are only logged with the
index of the sample the behaviour had just seen, which is what a replay test checks (for
example, that ``stop`` came on the first sample over the contact threshold).
"""

from __future__ import annotations

from collections.abc import Sequence

from ext_sense_behaviours.records import ArmState


class ReplayArm:
    """Hands out recorded :class:`ArmState` samples one per :meth:`read_state` call.

    Args:
        states: The recorded samples in order.
    """

    def __init__(self, states: Sequence[ArmState]) -> None:
        self._states = list(states)
        self.index = -1
        self.commands: list[tuple[int, str]] = []

    def read_state(self) -> ArmState | None:
        """The next sample, or ``None`` after the last."""
        if self.index + 1 >= len(self._states):
            return None
        self.index += 1
        return self._states[self.index]

    def take_failure(self) -> None:
        """A recording's motion never fails."""
        return None

    def move_down(self, speed_mps: float) -> None:
        """Log the command (the recording moves by itself)."""
        self.commands.append((self.index, f"move_down {speed_mps:.4f}"))

    def stop(self) -> None:
        """Log the command."""
        self.commands.append((self.index, "stop"))

    def retract(self, height_m: float, speed_mps: float) -> None:
        """Log the command."""
        self.commands.append((self.index, f"retract {height_m:.4f}"))

    def first_index(self, command: str) -> int | None:
        """Sample index at which ``command`` (its first word) was first given."""
        for index, text in self.commands:
            if text.split()[0] == command:
                return index
        return None
