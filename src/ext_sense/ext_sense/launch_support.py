"""Turning a :class:`~ext_sense.graph.GraphSpec` into a ``launch`` description.

The launch files under ``launch/`` are one line each: they call
:func:`generate_launch_description_for` with their graph's name. ``launch`` and ``launch_ros``
are imported here only, lazily, because they exist on a ROS 2 install but not on PyPI.
"""

from __future__ import annotations

from typing import Any

from ext_sense.graph import as_bool, launch_node_kwargs
from ext_sense.graph_model import with_model
from ext_sense.graphs import GRAPHS


def generate_launch_description_for(graph_name: str) -> Any:
    """The ``LaunchDescription`` of one graph: its arguments, then its nodes.

    Nodes are built in an ``OpaqueFunction`` once the launch arguments are resolved, by the same
    ``GraphSpec.build`` that ``ext-sense run`` calls; a node marked ``required`` shuts the whole
    launch down when it exits. Before any node is built, the graph's model is looked up as
    ``ext-sense run`` does (:func:`ext_sense.graph_model.with_model`): with no usable model the
    function raises, so the launch fails before any process starts and ``ros2 launch`` prints
    the message (which places were searched, which command creates the models) and exits 1.
    """
    from launch import LaunchDescription
    from launch.actions import DeclareLaunchArgument, OpaqueFunction, Shutdown
    from launch.substitutions import LaunchConfiguration
    from launch_ros.actions import Node

    graph = GRAPHS[graph_name]

    def _nodes(context: Any) -> list[Any]:
        values = {a.name: LaunchConfiguration(a.name).perform(context) for a in graph.arguments}
        values = with_model(graph, values)  # ModelMissingError: nothing is started
        use_sim_time = as_bool(values["use_sim_time"])
        actions = []
        for spec in graph.nodes(values):
            kwargs = launch_node_kwargs(spec, use_sim_time)
            if spec.required:
                kwargs["on_exit"] = Shutdown(reason=f"{spec.name} finished")
            actions.append(Node(**kwargs))
        return actions

    declared = [
        DeclareLaunchArgument(
            a.name,
            default_value=a.default,
            description=a.description,
            **({"choices": list(a.choices)} if a.choices else {}),
        )
        for a in graph.arguments
    ]
    return LaunchDescription([*declared, OpaqueFunction(function=_nodes)])
