"""Plain records the behaviours consume, so the state machines never see a ROS message.

Nodes convert ``ext_sense_msgs/ContactEstimate`` into :class:`Estimate` and the arm adapters
deliver :class:`ArmState`; tests build both directly.
"""

from __future__ import annotations

import math
from typing import NamedTuple


class Estimate(NamedTuple):
    """The fields of ``ContactEstimate`` the behaviours use.

    Attributes:
        stamp_ns: Contact onset (motion start for food), integer ns.
        task: ``"tap_localization"``, ``"handover_stability"`` or ``"food_identification"``.
        provisional: An anytime estimate from a shortened window.
        stability_probability: P(stable grasp), 0..1 (NaN when not handover).
        class_label: Food class or ``"stable"``/``"unstable"`` (empty otherwise).
        tap_position_m: Tap distance from the held end, metres (NaN otherwise).
        tap_position_std_m: Its standard deviation, metres (NaN when unknown).
        model_id: The model that produced it.
        class_probabilities: Probabilities in the order of the model's class names.
    """

    stamp_ns: int
    task: str
    provisional: bool = False
    stability_probability: float = math.nan
    class_label: str = ""
    tap_position_m: float = math.nan
    tap_position_std_m: float = math.nan
    model_id: str = ""
    class_probabilities: tuple[float, ...] = ()


class ArmState(NamedTuple):
    """One state sample of the arm.

    Attributes:
        stamp_ns: Time of the sample, integer ns.
        z_m: End-effector height in the base frame, metres.
        force_n: External force on the end effector in the base frame (x, y, z), newtons
            (franka: the first three components of ``O_F_ext_hat_K``).
        velocity_z_mps: End-effector vertical velocity, m/s (negative going down).
    """

    stamp_ns: int
    z_m: float
    force_n: tuple[float, float, float]
    velocity_z_mps: float = 0.0

    @property
    def force_norm_n(self) -> float:
        """Norm of the external force, newtons (NaN if any component is NaN)."""
        fx, fy, fz = self.force_n
        return math.sqrt(fx * fx + fy * fy + fz * fz)
