"""The Panda's recorded state from the ROS 1 food-poking bags, replayed as an arm adapter.

Test helpers (the real-bag replay tests): :func:`read_franka_bag` reads
``franka_msgs/msg/FrankaState``, which ``rosbags`` has no type for in its stores, so the type
is registered from the definition the bag carries in its connection header. The external
wrench ``O_F_ext_hat_K`` is in the base frame (force x, y, z in N, then torque in Nm); the
height is the translation z of ``O_T_EE`` (column-major 4 x 4, element 14).
:class:`ReplayArm` hands the recorded states to a behaviour and only logs its commands (the
recorded arm moved on its own) with the index of the sample it had just seen.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import NamedTuple

import numpy as np
import numpy.typing as npt

from ext_sense_behaviours.errors import BehaviourError
from ext_sense_behaviours.records import ArmState
from ext_sense_runtime.stamps import stamp_to_ns

FRANKA_STATE_TOPIC = "franka_state_controller"
FRANKA_STATE_TYPE = "franka_msgs/msg/FrankaState"


class FrankaTrace(NamedTuple):
    """One bag's arm states as arrays (``n`` messages, in recording order).

    Attributes:
        t_ns: Host time the recorder received each message, epoch ns, ``(n,)`` int64.
        stamp_ns: The message header stamp, epoch ns, ``(n,)`` int64.
        wrench: ``O_F_ext_hat_K``, ``(n, 6)`` float64: force N (x, y, z), torque Nm.
        z_m: End-effector height (``O_T_EE[14]``), metres, ``(n,)`` float64.
        velocity_z_mps: ``cartesian_velocity[2]`` when the definition has it, else NaN.
        robot_mode: ``robot_mode`` (2 = MOVE), ``(n,)`` uint8.
    """

    t_ns: npt.NDArray[np.int64]
    stamp_ns: npt.NDArray[np.int64]
    wrench: npt.NDArray[np.float64]
    z_m: npt.NDArray[np.float64]
    velocity_z_mps: npt.NDArray[np.float64]
    robot_mode: npt.NDArray[np.uint8]

    @property
    def force_norm_n(self) -> npt.NDArray[np.float64]:
        """Norm of the external force per message, N, ``(n,)``."""
        return np.linalg.norm(self.wrench[:, :3], axis=1)

    def states(self, use_header_stamp: bool = True) -> list[ArmState]:
        """The trace as :class:`ArmState` samples, stamped by header or by arrival."""
        stamps = self.stamp_ns if use_header_stamp else self.t_ns
        return [
            ArmState(
                int(stamps[i]),
                float(self.z_m[i]),
                (float(self.wrench[i, 0]), float(self.wrench[i, 1]), float(self.wrench[i, 2])),
                float(self.velocity_z_mps[i]),
            )
            for i in range(len(stamps))
        ]


def read_franka_bag(path: str | Path, topic: str = FRANKA_STATE_TOPIC) -> FrankaTrace:
    """Read every FrankaState message of ``topic`` from a ROS 1 bag.

    Args:
        path: The ``.bag`` file.
        topic: Topic holding ``franka_msgs/msg/FrankaState``.

    Returns:
        The trace, in recording order.

    Raises:
        BehaviourError: The file is missing or unreadable, the topic is absent or empty, or
            its type cannot be registered from the bag's own definition.
    """
    from rosbags.rosbag1 import Reader
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore

    path = Path(path)
    if not path.is_file():
        raise BehaviourError(f"The bag file '{path}' does not exist.")
    rows: dict[str, list] = {k: [] for k in FrankaTrace._fields}
    try:
        with Reader(path) as reader:
            connections = [c for c in reader.connections if c.topic == topic]
            if not connections:
                topics = sorted({c.topic for c in reader.connections})
                raise BehaviourError(
                    f"The bag '{path.name}' has no topic '{topic}'. Topics: {topics}."
                )
            store = get_typestore(Stores.ROS1_NOETIC)
            for conn in connections:
                store.register(get_types_from_msg(conn.msgdef.data, conn.msgtype))
            for conn, t_ns, raw in reader.messages(connections=connections):
                msg = store.deserialize_ros1(raw, conn.msgtype)
                rows["t_ns"].append(t_ns)
                rows["stamp_ns"].append(stamp_to_ns(msg.header.stamp))
                rows["wrench"].append(np.asarray(msg.O_F_ext_hat_K, dtype=np.float64))
                rows["z_m"].append(float(msg.O_T_EE[14]))
                vel = getattr(msg, "cartesian_velocity", None)
                rows["velocity_z_mps"].append(
                    float(vel[2]) if vel is not None and len(vel) > 2 else np.nan
                )
                rows["robot_mode"].append(int(msg.robot_mode))
    except BehaviourError:
        raise
    except Exception as err:  # rosbags raises several types for corrupt bags and bad defs
        raise BehaviourError(f"Cannot read FrankaState from '{path}': {err}") from err
    if not rows["t_ns"]:
        raise BehaviourError(f"The bag '{path.name}' has no messages on '{topic}'.")
    return FrankaTrace(
        np.asarray(rows["t_ns"], dtype=np.int64),
        np.asarray(rows["stamp_ns"], dtype=np.int64),
        np.vstack(rows["wrench"]),
        np.asarray(rows["z_m"], dtype=np.float64),
        np.asarray(rows["velocity_z_mps"], dtype=np.float64),
        np.asarray(rows["robot_mode"], dtype=np.uint8),
    )


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
