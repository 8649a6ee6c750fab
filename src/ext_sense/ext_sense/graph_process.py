"""Which nodes of a graph share a process: the ``hot_path`` argument and the process groups.

With ``hot_path:=one_process`` (the default) the driver, ``contact_window`` and
``contact_inference`` run on one executor in one process, handing packets and windows over in
process (:mod:`ext_sense_runtime.intra_process`); ``processes`` gives each node its own. rclpy
has no component containers, so a group is the ``node_group`` executable
(:func:`ext_sense.runner.main`) given the node specs as JSON, started by ``ext-sense run`` and
the launch files alike from :func:`process_groups`.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import replace

from ext_sense.graph import ArgumentSpec, NodeSpec

HOT_PATH = "hot_path"
"""The process name of the hot path's group."""

HOT_PATH_EXECUTABLES = frozenset(
    {"nuskin_driver", "biotac_driver", "contact_window", "contact_inference"}
)
"""The nodes on the hot path from the sensor to ``/extsense/contact_estimate``."""

PROCESS_ARGUMENTS: tuple[ArgumentSpec, ...] = (
    ArgumentSpec(
        "hot_path",
        "one_process",
        "one_process: the sensor driver, contact_window and contact_inference in one process on "
        "one executor (the node_group executable; fewer wake-ups per window, the three share "
        "one core and one GIL); processes: every node its own process.",
        ("one_process", "processes"),
    ),
)


def place_hot_path(nodes: tuple[NodeSpec, ...], args: Mapping[str, str]) -> tuple[NodeSpec, ...]:
    """The graph's nodes with the hot path put in one process unless ``hot_path:=processes``."""
    if args.get("hot_path", "one_process") != "one_process":
        return nodes
    return tuple(
        replace(n, process=HOT_PATH) if n.executable in HOT_PATH_EXECUTABLES else n for n in nodes
    )


def process_groups(nodes: tuple[NodeSpec, ...]) -> list[tuple[str, tuple[NodeSpec, ...]]]:
    """The processes to start, in order: ``(name, nodes)``; a node with no ``process`` alone."""
    groups: dict[str, list[NodeSpec]] = {}
    for spec in nodes:
        groups.setdefault(spec.process or spec.name, []).append(spec)
    return [(name, tuple(specs)) for name, specs in groups.items()]
