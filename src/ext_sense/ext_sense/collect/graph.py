"""The task graph as ``ext-sense collect`` runs it: the same nodes, a few wires changed.

The simulator's truth moves to ``/extsense/sim/ground_truth`` (the session's labels are the
operator's); the food behaviour starts probes only when asked; a scripted handover on the
simulator plays each grasp when collect triggers it, as the pending answer's class. The
simulated device starts its trials once the collector subscribes to its truth, which the
collector does only once the sensor stream reaches its recording: discovery matches each topic
on its own, so the first trial is in the bag, packets included, even when that takes seconds.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence

from ext_sense.graph import NodeSpec

SIM_TRUTH_TOPIC = "/extsense/sim/ground_truth"
COLLECTOR_NODE = "collector"
"""The node recording the session: the simulated device waits for its subscription."""
COLLECTOR_WAIT_S = 60.0
"""How long the simulated device waits for the collector before its first trial, s."""
STREAM_WAIT_S = 30.0
"""How long the collector waits for the sensor stream to reach it before it subscribes to the
simulator's truth anyway (which lets the simulated device start), s."""
MATCH_SETTLE_S = 1.0
"""After a publisher shows in the graph, how long its connection to our subscription may take."""
SIM_TRIGGER_TOPIC = "/extsense/sim/trigger"
GROUND_TRUTH = "/extsense/ground_truth"


SIM_FOOD_WINDOW_END_S = 4.0
"""Against the simulator the probe retracts 4 s after its motion start (8 s: a real arm's)."""


def collect_nodes(
    task: str, nodes: Sequence[NodeSpec], sim: bool = False, sim_trigger: bool = False
) -> list[NodeSpec]:
    """``nodes`` rewired for collecting (see the module docstring); the monitor is dropped.

    ``sim`` shortens food probes; ``sim_trigger`` has collect trigger the simulated grasps.
    """
    out = []
    for spec in nodes:
        if spec.executable == "estimate_monitor":
            continue
        remaps = tuple((a, SIM_TRUTH_TOPIC if b == GROUND_TRUTH else b) for a, b in spec.remappings)
        if sim_trigger and task == "handover_stability" and spec.executable == "sim_device":
            remaps = tuple((a, SIM_TRIGGER_TOPIC if a == "trigger" else b) for a, b in remaps)
        params = dict(spec.parameters)
        if spec.executable == "sim_device":  # no trial before the session's bag can hear it
            params |= {"wait_for_listener_s": COLLECTOR_WAIT_S, "listener_node": COLLECTOR_NODE}
        if spec.executable == "food_behaviour":
            params |= {"auto_start": False, "repeat_s": 0.0}
            if sim:
                params.setdefault("window_end_s", SIM_FOOD_WINDOW_END_S)
        out.append(dataclasses.replace(spec, remappings=remaps, parameters=params))
    return out
