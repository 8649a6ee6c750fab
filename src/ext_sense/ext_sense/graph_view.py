"""The live view's part of every graph: the ``view`` arguments and the ``foxglove_view`` node.

Kept out of :mod:`ext_sense.graphs` (its build functions call :func:`view_nodes`), so both front
ends (``ext-sense run`` and the launch files, which read the same description) take
``view:=true`` with no change of their own.
"""

from __future__ import annotations

from collections.abc import Mapping

from ext_sense.graph import ArgumentSpec, NodeSpec, as_bool

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


def view_nodes(args: Mapping[str, str], stream: tuple[str, str]) -> tuple[NodeSpec, ...]:
    """The ``foxglove_view`` node when ``view:=true``, else nothing.

    Args:
        args: The graph's resolved arguments.
        stream: The driver's relative output topic and its absolute name.
    """
    if not as_bool(args.get("view", "false")):
        return ()
    sensor = args["sensor"]
    return (
        NodeSpec(
            package="ext_sense",
            executable="foxglove_view",
            name="foxglove_view",
            plugin="ext_sense.nodes.foxglove_view:FoxgloveViewNode",
            parameters={
                "sensor": sensor,
                "host": args["view_host"],
                "port": int(args["view_port"]),
                "display_rate_hz": float(args["view_rate"]),
            },
            remappings=(
                stream,
                ("contact_estimate", "/extsense/contact_estimate"),
                ("ground_truth", "/extsense/ground_truth"),
                ("window", "/extsense/contact_window"),
            ),
        ),
    )
