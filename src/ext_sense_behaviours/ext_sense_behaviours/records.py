"""Plain records the behaviours consume, so the state machines never see a ROS message.

The arm adapters deliver :class:`ArmState`. Estimates are the shared
:class:`ext_sense_runtime.records.Estimate`: the nodes convert ``ext_sense_msgs/ContactEstimate``
with :func:`ext_sense_runtime.records.estimate_of`. Tests build both directly.
"""

from __future__ import annotations

import math
from typing import NamedTuple


class ArmState(NamedTuple):
    """One state sample of the arm: end-effector height and external force in the base frame.

    ``force_n`` (x, y, z) is franka's first three components of ``O_F_ext_hat_K``;
    ``velocity_z_mps`` is negative going down.
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
