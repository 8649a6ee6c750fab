"""Which nodes of a graph share a process: the ``hot_path`` argument and the process groups.

By default (``hot_path:=one_process``) the hot path, the sensor driver, ``contact_window`` and
``contact_inference``, runs in one process on one executor (``NodeSpec.process`` "hot_path"):
packets and windows are handed from callback to callback in that process
(:mod:`ext_sense_runtime.intra_process`, as rclcpp's intra-process comms) instead of through
the middleware and two more wake-ups; the three share one core and one GIL.
``hot_path:=processes`` gives every node its own process, as ``ros2 launch`` starts Python
nodes (a crash stays in one node). The other nodes (simulator, monitor, view, behaviours) are
a process each either way.

rclpy has no component containers (``ComposableNodeContainer`` loads C++ components only), so
one process for Python nodes is one executable running several nodes on one executor: the
``node_group`` console script of this package (:func:`ext_sense.runner.main`), given the node
specs as JSON. ``ext-sense run`` (:func:`ext_sense.runner.run_graph`) starts a group as that
process, and the launch files (:mod:`ext_sense.launch_support`) start it as one
``launch_ros`` ``Node`` action of that executable; both read the groups from
:func:`process_groups`. Kept out of :mod:`ext_sense.graphs` so it stays one description.
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
    """The graph's nodes with the hot path put in one process unless ``hot_path:=processes``.

    Args:
        nodes: The nodes the graph's build function made.
        args: The graph's resolved arguments.
    """
    if args.get("hot_path", "one_process") != "one_process":
        return nodes
    return tuple(
        replace(n, process=HOT_PATH) if n.executable in HOT_PATH_EXECUTABLES else n for n in nodes
    )


def process_groups(nodes: tuple[NodeSpec, ...]) -> list[tuple[str, tuple[NodeSpec, ...]]]:
    """The processes to start, in start order: ``(name, nodes)`` each.

    A node with no :attr:`~ext_sense.graph.NodeSpec.process` is a process of its own, named as
    the node; nodes sharing a process name are one process, started where its first node is.
    """
    groups: dict[str, list[NodeSpec]] = {}
    for spec in nodes:
        groups.setdefault(spec.process or spec.name, []).append(spec)
    return [(name, tuple(specs)) for name, specs in groups.items()]
