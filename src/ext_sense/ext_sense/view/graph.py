"""The live view's part of every graph: the ``view`` arguments and the ``foxglove_view`` node.

Both front ends take ``view:=true`` through :func:`view_nodes`; ``ext-sense replay BAG
view:=true`` starts the same node through :func:`replay_view_graph`.
"""

from __future__ import annotations

from collections.abc import Mapping

from ext_sense.graph import ArgumentSpec, GraphSpec, NodeSpec, as_bool
from ext_sense.topics import (
    ESTIMATE_REMAPS,
    SENSOR_PACKETS,
    TOPIC_GROUND_TRUTH,
    TOPIC_WINDOW,
)

VIEW_ARGUMENTS: tuple[ArgumentSpec, ...] = (
    ArgumentSpec(
        "view",
        "false",
        "Start the live Foxglove view (foxglove_view): a WebSocket server at "
        "ws://view_host:view_port for the Foxglove app (docs/view.md).",
        ("true", "false"),
    ),
    ArgumentSpec(
        "view_host",
        "127.0.0.1",
        "Address the view's server listens on. The protocol has no authentication: another "
        "address shows every channel to anyone who reaches it (docs/view.md, Security).",
    ),
    ArgumentSpec(
        "view_port", "8765", "TCP port of the view's server.", kind=int, low=0, high=65535
    ),
    ArgumentSpec(
        "view_rate",
        "15",
        "Frames the view sends per second.",
        kind=float,
        low=1,
        high=30,
    ),
)


def view_nodes(args: Mapping[str, str]) -> tuple[NodeSpec, ...]:
    """The ``foxglove_view`` node (a process of its own) when ``view:=true``, else nothing."""
    if not as_bool(args.get("view", "false")):
        return ()
    sensor = args["sensor"]
    return (
        NodeSpec(
            package="ext_sense",
            executable="foxglove_view",
            name="foxglove_view",
            plugin="ext_sense.view.node:FoxgloveViewNode",
            parameters={
                "sensor": sensor,
                "host": args["view_host"],
                "port": int(args["view_port"]),
                "display_rate_hz": float(args["view_rate"]),
            },
            remappings=(
                ("packets", SENSOR_PACKETS[sensor]),
                *ESTIMATE_REMAPS,
                ("ground_truth", TOPIC_GROUND_TRUTH),
                ("window", TOPIC_WINDOW),
            ),
        ),
    )


def replay_view_graph(sensor: str) -> GraphSpec:
    """The view alone as a graph of ``sensor``, for ``ext-sense replay BAG view:=true``."""
    return GraphSpec(
        name="replay",
        description="The live Foxglove view of a replayed bag.",
        arguments=VIEW_ARGUMENTS,
        build=lambda values: view_nodes({**values, "sensor": sensor}),
    )
