"""The node graphs of ext_sense: one description each, for launch files and ``ext-sense run``.

Every graph runs source -> driver -(packets)-> contact_window -(window)-> contact_inference
-> ``/extsense/contact_estimate`` (final) and ``.../provisional``, read by the behaviours and
the estimate monitor. :mod:`ext_sense.launch_support` and :mod:`ext_sense.runner` start them.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import replace

from ext_sense.graph import (
    ArgumentSpec,
    GraphSpec,
    NodeSpec,
    ParameterValue,
    as_bool,
)
from ext_sense.graph_process import PROCESS_ARGUMENTS, place_hot_path
from ext_sense.graph_sources import DEFAULT_SCENES as DEFAULT_SCENES
from ext_sense.graph_sources import MONITOR_NODE, PACKET_ARGUMENTS, needed_files, source_nodes
from ext_sense.graph_sources import SIM_TRIGGERS as SIM_TRIGGERS
from ext_sense.topics import (
    ESTIMATE_REMAPS,
    SENSOR_PACKETS,
    TOPIC_ESTIMATE,
    TOPIC_GROUND_TRUTH,
    TOPIC_HANDOVER_OFFER,
    TOPIC_MOTION_START,
    TOPIC_TAP_MARKER,
    TOPIC_WINDOW,
)
from ext_sense.view.graph import VIEW_ARGUMENTS, view_nodes

SENSORS = ("nuskin", "biotac")
SOURCES = ("sim", "serial", "can", "bag")
BACKENDS = ("onnx", "sklearn")


def _common_arguments(default_trials: str) -> tuple[ArgumentSpec, ...]:
    return (
        ArgumentSpec("sensor", "nuskin", "Tactile sensor on the fingers.", SENSORS),
        ArgumentSpec(
            "source",
            "sim",
            "Where the sensor bytes come from: the simulator's emulated device, a serial "
            "port, a CAN channel, or a recorded bag.",
            SOURCES,
        ),
        ArgumentSpec(
            "port",
            "",
            "Serial device of the sensor (source serial), or the path where the simulated "
            "device links its pty (source sim; empty: a path under /tmp).",
        ),
        ArgumentSpec(
            "baud", "4000000", "Serial baud rate (source serial).", kind=int, low=1, high=100e6
        ),
        ArgumentSpec(
            "can_channel",
            "",
            "CAN channel (source can, or source sim over CAN when set, e.g. 'vcan_extsense').",
        ),
        ArgumentSpec("can_interface", "socketcan", "python-can interface (source can)."),
        ArgumentSpec("bag", "", "rosbag2 directory or .mcap file to replay (source bag)."),
        ArgumentSpec("scene", "", "Simulator scene name or YAML path (empty: the task's default)."),
        ArgumentSpec(
            "trials",
            default_trials,
            "Simulated trials; 0 runs until stopped.",
            kind=int,
            low=0,
            high=1e6,
        ),
        ArgumentSpec("seed", "0", "Simulator random seed.", kind=int, low=0, high=2**32 - 1),
        ArgumentSpec("model", "", "Model bundle directory (empty: the task's default model)."),
        ArgumentSpec(
            "held_object",
            "",
            "The object the fingers hold, kind or kind:length_m (e.g. rod:0.30): a model whose "
            "card records another object is refused; empty: the scene's object with source sim, "
            "else not checked.",
        ),
        ArgumentSpec("backend", "onnx", "Inference backend.", BACKENDS),
        ArgumentSpec(
            "monitor",
            "true",
            "Print estimates beside ground truth and stop after the last trial.",
            ("true", "false"),
        ),
        ArgumentSpec(
            "behaviours",
            "false",
            "Start the task's behaviour nodes. With source sim the simulated device follows "
            "them: a trial when the food probe starts moving, a grasp of grasp_trials trials "
            "when the handover offers the object.",
            ("true", "false"),
        ),
        ArgumentSpec(
            "sim_labels",
            "",
            "behaviours:=true with source sim: classes of the simulated trials of successive "
            "probes or grasps, comma separated, cycled (e.g. 'stable,unstable' or "
            "'apple,water'); empty: as the scene draws them.",
        ),
        ArgumentSpec(
            "use_sim_time", "false", "Use /clock (bag replay with clock).", ("true", "false")
        ),
        ArgumentSpec(
            "manage_drivers",
            "true",
            "Configure and activate the lifecycle nodes (the sensor driver, the gripper); "
            "false leaves them to an external lifecycle manager.",
            ("true", "false"),
        ),
        *PACKET_ARGUMENTS,
        *VIEW_ARGUMENTS,
        *PROCESS_ARGUMENTS,
    )


def _perception_nodes(task: str, args: Mapping[str, str]) -> tuple[NodeSpec, ...]:
    sensor = args["sensor"]
    packets = ("packets", SENSOR_PACKETS[sensor])
    # Food windows start at the arm's motion start: the ground truth's stamp from the simulator
    # or a bag, else (and with behaviours:=true) the probe's own on /extsense/motion_start.
    motion = (
        TOPIC_GROUND_TRUTH
        if args["source"] in ("sim", "bag") and not as_bool(args["behaviours"])
        else TOPIC_MOTION_START
    )
    return (
        NodeSpec(
            package="ext_sense_perception",
            executable="contact_window",
            name="contact_window",
            plugin="ext_sense_perception.nodes.contact_window:ContactWindowNode",
            parameters={
                "task": task,
                "sensor": sensor,
                "model_path": args["model"],
            },
            remappings=(
                packets,
                ("window", TOPIC_WINDOW),
                ("motion_start", motion),
            ),
        ),
        NodeSpec(
            package="ext_sense_perception",
            executable="contact_inference",
            name="contact_inference",
            plugin="ext_sense_perception.nodes.contact_inference:ContactInferenceNode",
            parameters={
                "task": task,
                "sensor": sensor,
                "backend": args["backend"],
                "model_path": args["model"],
                "held_object": args["held_object"],
            },
            remappings=(("window", TOPIC_WINDOW), *ESTIMATE_REMAPS),
        ),
    )


MONITOR_IDLE_TIMEOUT_S = {
    "tap_localization": 5.0,
    "handover_stability": 5.0,
    "food_identification": 15.0,
}
"""How long the monitor waits without news, once it has seen every trial, before it ends the
graph: food's estimates lag their truth by a 3 s window plus processing."""


def _monitor_nodes(task: str, args: Mapping[str, str]) -> tuple[NodeSpec, ...]:
    if not as_bool(args["monitor"]):
        return ()
    trials = int(args["trials"])
    return (
        NodeSpec(
            package="ext_sense",
            executable="estimate_monitor",
            name=MONITOR_NODE,
            plugin="ext_sense.nodes.estimate_monitor:EstimateMonitorNode",
            parameters={
                "task": task,
                "expected": trials,
                "idle_timeout_s": MONITOR_IDLE_TIMEOUT_S[task],
                # a sensor has no truth behind it: estimates are counted unscored
                "ground_truth": args["source"] in ("sim", "bag"),
            },
            remappings=(*ESTIMATE_REMAPS, ("ground_truth", TOPIC_GROUND_TRUTH)),
            required=trials > 0,
        ),
    )


def _behaviour(
    executable: str,
    plugin_class: str,
    parameters: Mapping[str, ParameterValue] | None = None,
    remappings: tuple[tuple[str, str], ...] = ESTIMATE_REMAPS,
) -> NodeSpec:
    """A node of ``ext_sense_behaviours`` named after its executable."""
    return NodeSpec(
        package="ext_sense_behaviours",
        executable=executable,
        name=executable,
        plugin=f"ext_sense_behaviours.nodes.{executable}:{plugin_class}",
        parameters=dict(parameters or {}),
        remappings=remappings,
    )


def _tap_behaviours(args: Mapping[str, str]) -> tuple[NodeSpec, ...]:
    return (
        _behaviour(
            "tap_marker",
            "TapMarkerNode",
            remappings=(*ESTIMATE_REMAPS, ("marker", TOPIC_TAP_MARKER)),
        ),
    )


SIM_FOOD_ARM = {"start_z_m": 0.16, "surface_z_m": 0.152, "stiffness_n_per_m": 500.0}
"""The simulated arm (``sim_arm``) against the food scene: the tines touch 8 mm below the start;
a 500 N/m spring takes 2 s at 1 cm/s from the probe's 10 N contact to the 20 N reflex, slack
for a loaded machine (docs/decisions.md, "The simulated food arm")."""

SIM_FOOD_STOP_HEIGHT_M = 0.125
"""The probe's preset stop over the simulated arm: the scene's 35 mm travel from the start."""

SIM_FOOD_START_DELAY_S = 2.0
"""The simulated food probe's first start, s after start-up at the earliest: a recorder started
with the graph missed the simulated sensor's first truth, published 0.1 s after the graph came
up, about one run in five (``test_behaviour_scenarios.py``)."""

SIM_ARM_STATE_TIMEOUT_S = 2.0
"""The probe's arm-state timeout over the simulated arm (0.5 s on a robot): ``sim_arm``'s 100 Hz
Python states share the CPU with the graph (a 0.62 s pause was seen)."""

SIM_ARM_ACCEPT_TIMEOUT_S = 5.0
"""The probe's goal-acceptance deadline over the simulated arm (2 s on a robot), as above."""


def _handover_behaviours(args: Mapping[str, str]) -> tuple[NodeSpec, ...]:
    handover: dict[str, ParameterValue] = {"timeout_s": float(args["handover_timeout_s"])}
    if args["source"] == "sim":
        # offer the next simulated grasp once the device listens and the model has loaded
        handover |= {"regrasp_s": 1.0, "start_subscribers": 1, "start_delay_s": 4.0}
    # a lifecycle node, as the drivers: the front end (or an external manager) drives it
    gripper = _behaviour(
        "robotiq_gripper", "RobotiqGripperNode", {"port": args["gripper_port"], "autostart": False}
    )
    gripper = replace(
        gripper, remappings=(), lifecycle=True, manage=as_bool(args["manage_drivers"])
    )
    return (
        gripper,
        _behaviour(
            "handover_behaviour",
            "HandoverBehaviourNode",
            handover,
            remappings=(*ESTIMATE_REMAPS, ("handover/offer", TOPIC_HANDOVER_OFFER)),
        ),
    )


def _food_behaviours(args: Mapping[str, str]) -> tuple[NodeSpec, ...]:
    # the franka_ros2 adapter always; with arm:=sim the sim_arm node serves its interfaces
    food: dict[str, ParameterValue] = {"arm": "franka"}
    arm: tuple[NodeSpec, ...] = ()
    if args["arm"] == "sim":
        food["stop_height_m"] = SIM_FOOD_STOP_HEIGHT_M
        food["state_timeout_s"] = SIM_ARM_STATE_TIMEOUT_S
        food["franka.accept_timeout_s"] = SIM_ARM_ACCEPT_TIMEOUT_S
        plugin = "ext_sense_sim.nodes.sim_arm:SimArmNode"
        arm = (NodeSpec("ext_sense_sim", "sim_arm", "sim_arm", plugin, dict(SIM_FOOD_ARM)),)
    if args["source"] == "sim":
        # probe by itself, once the window node and the simulated device hear the motion start
        # and listeners started beside the graph have had time to match the device's truth
        food |= {
            "auto_start": True,
            "repeat_s": 2.0,
            "start_subscribers": 2,
            "start_delay_s": SIM_FOOD_START_DELAY_S,
        }
    probe = _behaviour(
        "food_behaviour",
        "FoodBehaviourNode",
        food,
        remappings=(*ESTIMATE_REMAPS, ("motion_start", TOPIC_MOTION_START)),
    )
    return (*arm, probe)


def _chain(
    task: str, behaviours: Callable[[Mapping[str, str]], tuple[NodeSpec, ...]]
) -> Callable[[Mapping[str, str]], tuple[NodeSpec, ...]]:
    """The build function of a task's graph: source, driver, perception, behaviours, monitor."""

    def build(args: Mapping[str, str]) -> tuple[NodeSpec, ...]:
        return place_hot_path(
            source_nodes(task, args)
            + _perception_nodes(task, args)
            + (behaviours(args) if as_bool(args["behaviours"]) else ())
            + _monitor_nodes(task, args)
            + view_nodes(args),
            args,
        )

    return build


GRAPHS: dict[str, GraphSpec] = {
    "tap_localization": GraphSpec(
        name="tap_localization",
        description=f"Where was the held rod tapped? Tap position on {TOPIC_ESTIMATE}.",
        arguments=_common_arguments("30"),
        build=_chain("tap_localization", _tap_behaviours),
        files=needed_files("tap_localization"),
    ),
    "handover": GraphSpec(
        name="handover",
        description="Is the person's grasp stable during a robot-to-human handover?",
        arguments=(
            *_common_arguments("10"),
            ArgumentSpec("gripper_port", "", "Serial device of the Robotiq 2F gripper."),
            ArgumentSpec(
                "grasp_trials",
                "4",
                "behaviours:=true with source sim: simulated trials (contact windows) per "
                "person's grasp; trials:=N then makes N / grasp_trials handovers.",
                kind=int,
                low=1,
                high=1000,
            ),
            ArgumentSpec(
                "handover_timeout_s",
                "30",
                "Handover safety timeout, s: no stable grasp by then, keep holding.",
                kind=float,
                low=0.1,
                high=3600,
            ),
        ),
        build=_chain("handover_stability", _handover_behaviours),
        files=needed_files("handover_stability"),
    ),
    "food_identification": GraphSpec(
        name="food_identification",
        description="Which food did the fork touch?",
        arguments=(
            *_common_arguments("7"),
            ArgumentSpec(
                "arm",
                "sim",
                "behaviours:=true: the probe's arm, sim (the sim_arm node, franka_ros2's "
                "interfaces) or franka (a franka_ros2 robot running fr3_arm_controller).",
                ("sim", "franka"),
            ),
        ),
        build=_chain("food_identification", _food_behaviours),
        files=needed_files("food_identification"),
    ),
}
