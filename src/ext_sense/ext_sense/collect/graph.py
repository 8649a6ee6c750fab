"""The task graph as ``ext-sense collect`` runs it: the same nodes, a few wires changed.

Plain data over :class:`ext_sense.graph.NodeSpec` (no ROS), so the changes are testable:

- the simulator's ground truth goes to ``/extsense/sim/ground_truth`` (and the window node's
  ``motion_start``, where it listened there, follows it): the session's labels on
  ``/extsense/ground_truth`` are the operator's, and the simulator's are kept apart to check
  them against;
- the behaviours start nothing by themselves: collect asks for each food probe after the
  operator has named the food (``auto_start`` and ``repeat_s`` off); the handover behaviour
  still offers the next grasp itself (``regrasp_s``), the operator judging each one after it;
- a scripted handover against the simulator (``sim_trigger``): the simulated person grasps when
  collect says so on :data:`SIM_TRIGGER_TOPIC`, not on the offer itself, so that collect can
  name the class each grasp is played as once it knows which answer is pending (a grasp that
  gave no contact window is played again as the same class).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence

from ext_sense.graph import NodeSpec

SIM_TRUTH_TOPIC = "/extsense/sim/ground_truth"
SIM_TRIGGER_TOPIC = "/extsense/sim/trigger"
GROUND_TRUTH = "/extsense/ground_truth"


SIM_FOOD_WINDOW_END_S = 4.0
"""Against the simulator the probe retracts 4 s after its motion start (the food window is 3 s;
the behaviour's 8 s default is for a real arm), so a scripted session takes seconds a trial."""


def collect_nodes(
    task: str, nodes: Sequence[NodeSpec], sim: bool = False, sim_trigger: bool = False
) -> list[NodeSpec]:
    """``nodes`` rewired for collecting (see the module docstring); the monitor is dropped.

    Args:
        task: Task name.
        nodes: The task graph's nodes.
        sim: The source is the simulator (shorter food probes: :data:`SIM_FOOD_WINDOW_END_S`).
        sim_trigger: Handover: the simulated device's grasps are triggered on
            :data:`SIM_TRIGGER_TOPIC` (by collect) instead of by the behaviour's offer.
    """
    out = []
    for spec in nodes:
        if spec.executable == "estimate_monitor":
            continue
        remaps = tuple((a, SIM_TRUTH_TOPIC if b == GROUND_TRUTH else b) for a, b in spec.remappings)
        if sim_trigger and task == "handover_stability" and spec.executable == "sim_device":
            remaps = tuple((a, SIM_TRIGGER_TOPIC if a == "trigger" else b) for a, b in remaps)
        params = dict(spec.parameters)
        if spec.executable == "food_behaviour":
            params |= {"auto_start": False, "repeat_s": 0.0}
            if sim:
                params.setdefault("window_end_s", SIM_FOOD_WINDOW_END_S)
        out.append(dataclasses.replace(spec, remappings=remaps, parameters=params))
    return out
