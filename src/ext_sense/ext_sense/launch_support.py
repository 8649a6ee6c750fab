"""Turning a :class:`~ext_sense.graph.GraphSpec` into a ``launch`` description.

The launch files call :func:`generate_launch_description_for` with their graph's name;
``launch`` and ``launch_ros`` (on a ROS 2 install, not on PyPI) are imported lazily here.
"""

from __future__ import annotations

from typing import Any

from ext_sense.graph import NodeSpec, as_bool, launch_node_kwargs
from ext_sense.graph_model import with_model
from ext_sense.graph_process import process_groups
from ext_sense.graphs import GRAPHS
from ext_sense.runner import group_payload


def generate_launch_description_for(graph_name: str) -> Any:
    """The ``LaunchDescription`` of one graph: its arguments, then its nodes.

    Nodes are built in an ``OpaqueFunction`` after the checks of ``ext-sense run`` (a failing
    one fails the launch before any process starts). A lifecycle node of its own process is
    configured and activated here (unless ``manage_drivers:=false``), one in a group by it.
    """
    from launch import LaunchDescription
    from launch.actions import DeclareLaunchArgument, OpaqueFunction, Shutdown
    from launch.substitutions import LaunchConfiguration
    from launch_ros.actions import Node

    graph = GRAPHS[graph_name]

    def _nodes(context: Any) -> list[Any]:
        values = {a.name: LaunchConfiguration(a.name).perform(context) for a in graph.arguments}
        graph.check_files(graph.resolve(values))  # GraphError: nothing is started
        values = with_model(graph, values)  # ModelMissingError: nothing is started
        use_sim_time = as_bool(values["use_sim_time"])
        actions = []
        for name, specs in process_groups(graph.nodes(values)):
            if len(specs) > 1:  # one process, one executor: the node_group executable
                actions.append(Node(**group_node_kwargs(name, specs, use_sim_time)))
                continue
            spec = specs[0]
            kwargs = launch_node_kwargs(spec, use_sim_time)
            if spec.required:
                kwargs["on_exit"] = Shutdown(reason=f"{spec.name} finished")
            if spec.lifecycle:
                actions += _lifecycle_actions(kwargs, spec.manage)
            else:
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


def group_node_kwargs(name: str, specs: tuple[NodeSpec, ...], use_sim_time: bool) -> dict[str, Any]:
    """``launch_ros.actions.Node`` keyword arguments of a group (each node's own in the JSON)."""
    from launch.actions import Shutdown

    kwargs: dict[str, Any] = {
        "package": "ext_sense",
        "executable": "node_group",
        "arguments": [group_payload(specs, use_sim_time)],
        "output": "screen",
        "emulate_tty": True,
    }
    if any(s.required for s in specs):
        kwargs["on_exit"] = Shutdown(reason=f"{name} finished")
    return kwargs


def _lifecycle_actions(kwargs: dict[str, Any], manage: bool) -> list[Any]:
    """A ``LifecycleNode`` and, when ``manage``, the events that configure and activate it."""
    from launch.actions import EmitEvent, RegisterEventHandler
    from launch.events import matches_action
    from launch_ros.actions import LifecycleNode
    from launch_ros.event_handlers import OnStateTransition
    from launch_ros.events.lifecycle import ChangeState
    from lifecycle_msgs.msg import Transition

    node = LifecycleNode(namespace="", **kwargs)
    if not manage:
        return [node]

    def change(transition_id: int) -> Any:
        return EmitEvent(
            event=ChangeState(
                lifecycle_node_matcher=matches_action(node), transition_id=transition_id
            )
        )

    activate_when_configured = RegisterEventHandler(
        OnStateTransition(
            target_lifecycle_node=node,
            start_state="configuring",
            goal_state="inactive",
            entities=[change(Transition.TRANSITION_ACTIVATE)],
        )
    )
    return [node, activate_when_configured, change(Transition.TRANSITION_CONFIGURE)]
