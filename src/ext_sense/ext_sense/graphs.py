"""The node graphs of ext_sense: one description each, for launch files and ``ext-sense run``.

Every graph runs the same chain, fed by one of four sources::

    source ──> driver ──events/frames──> contact_window ──window──> contact_inference
      (sim device on a pty or CAN,                                        │
       serial, CAN, or a bag)                          /extsense/contact_estimate
                                                                          │
                                                 behaviours, estimate_monitor

The functions here only describe; :mod:`ext_sense.launch_support` turns a description into
``launch_ros`` actions and :mod:`ext_sense.runner` starts the same nodes without ``launch``.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Mapping
from dataclasses import replace
from pathlib import Path

from ext_sense.graph import (
    ArgumentSpec,
    GraphError,
    GraphSpec,
    NodeSpec,
    ParameterValue,
    as_bool,
)
from ext_sense.graph_process import PROCESS_ARGUMENTS, place_hot_path
from ext_sense.graph_view import VIEW_ARGUMENTS, view_nodes

NS = "/extsense"
TOPIC_EVENTS = f"{NS}/nuskin/events"
TOPIC_FRAMES = f"{NS}/biotac/frames"
TOPIC_WINDOW = f"{NS}/contact_window"
TOPIC_ESTIMATE = f"{NS}/contact_estimate"
TOPIC_GROUND_TRUTH = f"{NS}/ground_truth"
TOPIC_TAP_MARKER = f"{NS}/tap_marker"
TOPIC_MOTION_START = f"{NS}/motion_start"
TOPIC_HANDOVER_OFFER = f"{NS}/handover/offer"

SENSORS = ("nuskin", "biotac")
STARTUP_SPARE_TRIALS = 3
"""Extra simulated trials: those streamed while the graph is still starting are lost."""
SOURCES = ("sim", "serial", "can", "bag")
BACKENDS = ("onnx", "sklearn")

DEFAULT_SCENES = {
    ("tap_localization", "nuskin"): "tap_rod30_nuskin",
    ("tap_localization", "biotac"): "tap_rod30_biotac",
    ("handover_stability", "nuskin"): "handover_rod_nuskin",
    ("handover_stability", "biotac"): "handover_plate_biotac",
    ("food_identification", "nuskin"): "food_fork_nuskin",
    ("food_identification", "biotac"): "food_fork_biotac",
}


def _common_arguments(default_trials: str) -> tuple[ArgumentSpec, ...]:
    return (
        ArgumentSpec("sensor", "nuskin", "Tactile sensor on the fingers.", SENSORS),
        ArgumentSpec(
            "source",
            "sim",
            "Where the sensor bytes come from: the scene simulator's emulated device, a "
            "serial port, a CAN channel, or a recorded bag.",
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
            "Start the task's behaviour nodes. With source sim the simulated device then "
            "follows them: it plays a trial when the food probe starts moving (its motion start "
            "put at the probe's) or a grasp of grasp_trials trials when the handover offers the "
            "object, silent in between.",
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
            "Configure and activate the lifecycle driver nodes (the sensor driver, and the "
            "gripper with behaviours); false leaves them unconfigured for an external "
            "lifecycle manager (e.g. nav2_lifecycle_manager, `ros2 lifecycle set`).",
            ("true", "false"),
        ),
        *VIEW_ARGUMENTS,
        *PROCESS_ARGUMENTS,
    )


def _sensor_topic(sensor: str) -> tuple[str, str]:
    """The driver's relative output topic and its absolute name."""
    return ("events", TOPIC_EVENTS) if sensor == "nuskin" else ("frames", TOPIC_FRAMES)


def _port(task: str, args: Mapping[str, str]) -> str:
    return args["port"] or f"/tmp/ext_sense_{task}_{args['sensor']}.pty"


def _needed_files(task: str) -> Callable[[Mapping[str, str]], None]:
    """The graph's check of the files its source needs (:meth:`GraphSpec.check_files`).

    A serial device is not checked: one plugged in after the start must work (the driver
    retries); the model is checked by :mod:`ext_sense.graph_model`.
    """

    def check(args: Mapping[str, str]) -> None:
        source, bag, scene = args["source"], args["bag"], args["scene"]
        if source == "bag" and not (bag and Path(bag).exists()):
            got = f"'{bag}': no such file or directory" if bag else "nothing"
            raise GraphError(
                f"The 'bag' argument must name an existing rosbag2 directory or .mcap/.db3 file "
                f"with source:=bag. Got {got}."
            )
        if source != "sim":
            return
        if not args["can_channel"]:
            port = Path(_port(task, args))
            if not (port.parent.is_dir() and os.access(port.parent, os.W_OK | os.X_OK)):
                raise GraphError(
                    f"The 'port' argument must be a path in an existing, writable directory (the "
                    f"simulated device links its pty there). Got '{port}': {port.parent} is not."
                )
        if scene.endswith((".yaml", ".yml")) and not Path(scene).is_file():
            raise GraphError(
                f"The 'scene' argument must be a scene name or an existing YAML "
                f"file. Got '{scene}': no such file."
            )

    return check


def _source_nodes(task: str, args: Mapping[str, str]) -> tuple[NodeSpec, ...]:
    """The device emulator or bag player, and the driver."""
    sensor, source = args["sensor"], args["source"]
    rel, topic = _sensor_topic(sensor)
    nodes: list[NodeSpec] = []
    if source == "bag":
        return (
            NodeSpec(
                package="ext_sense",
                executable="bag_player",
                name="bag_player",
                plugin="ext_sense.nodes.bag_player:BagPlayerNode",
                # start_delay_s: after its own subscribers appear, let the nodes downstream
                # (inference loading its model) come up before the first trial
                parameters={"bag": args["bag"], "rate": 1.0, "start_delay_s": 4.0},
                remappings=((rel, topic), ("ground_truth", TOPIC_GROUND_TRUTH)),
            ),
        )
    over_can = source == "can" or (source == "sim" and bool(args["can_channel"]))
    if source == "sim":
        trials = int(args["trials"])
        # the device streams from start-up, like a real one: trials sent before the driver has
        # the port are lost, so spare ones keep N scored trials
        stream: dict[str, ParameterValue] = {
            "trials": trials + STARTUP_SPARE_TRIALS if trials > 0 else 0
        }
        remaps: tuple[tuple[str, str], ...] = (("ground_truth", TOPIC_GROUND_TRUTH),)
        if as_bool(args["behaviours"]) and task in SIM_TRIGGERS:
            # the behaviour drives the scene: nothing streams before it asks, nothing is lost
            trigger_topic, align = SIM_TRIGGERS[task]
            stream = {
                "trials": trials,
                "mode": "trigger",
                "align": align,
                "labels": args["sim_labels"],
                "trials_per_trigger": int(args.get("grasp_trials", "1")),
            }
            remaps = (*remaps, ("trigger", trigger_topic))
        nodes.append(
            NodeSpec(
                package="ext_sense_sim",
                executable="sim_device",
                name="sim_device",
                plugin="ext_sense_sim.nodes.sim_device:SimDeviceNode",
                parameters={
                    "device": sensor,
                    "scene": args["scene"] or DEFAULT_SCENES[(task, sensor)],
                    "link": "can" if over_can else "pty",
                    "port_link": _port(task, args),
                    "can_channel": args["can_channel"],
                    **stream,
                    "seed": int(args["seed"]),
                },
                remappings=remaps,
            )
        )
    driver = "nuskin_driver" if sensor == "nuskin" else "biotac_driver"
    driver_class = "NuskinDriverNode" if sensor == "nuskin" else "BioTacDriverNode"
    nodes.append(
        NodeSpec(
            package="ext_sense_drivers",
            executable=driver,
            name=driver,
            plugin=f"ext_sense_drivers.nodes.{driver}:{driver_class}",
            parameters={
                "transport": "can" if over_can else "serial",
                "port": _port(task, args),
                "baud": int(args["baud"]),
                "can_interface": "virtual" if source == "sim" else args["can_interface"],
                "can_channel": args["can_channel"],
                **(
                    {"frame_id": "nuskin"} if sensor == "nuskin" else {"frame_id_prefix": "biotac_"}
                ),
                # a lifecycle node: the front end (or an external manager) drives it
                "autostart": False,
                # the emulated devices send nothing between trials (a real NUSkin receiver
                # sends its idle stream, a BioTac bridge 100 frames/s): no stall check on them
                **({"expected_rate_hz": 0.0} if source == "sim" else {}),
            },
            remappings=((rel, topic),),
            lifecycle=True,
            manage=as_bool(args["manage_drivers"]),
        )
    )
    return tuple(nodes)


def _perception_nodes(task: str, args: Mapping[str, str]) -> tuple[NodeSpec, ...]:
    sensor = args["sensor"]
    rel, topic = _sensor_topic(sensor)
    # Food windows start at the arm's motion start (contact_window's ``motion_start``): the
    # simulator and bags carry it as the ground truth's stamp; on the robot the food behaviour
    # publishes it on /extsense/motion_start.
    # With behaviours:=true the probe's own motion start cuts the window, whatever the source.
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
            # the window node cuts the windows of the model card's task profile
            parameters={"task": task, "sensor": sensor, "model_path": args["model"]},
            remappings=((rel, topic), ("window", TOPIC_WINDOW), ("motion_start", motion)),
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
            },
            remappings=(("window", TOPIC_WINDOW), ("contact_estimate", TOPIC_ESTIMATE)),
        ),
    )


MONITOR_IDLE_TIMEOUT_S = {
    "tap_localization": 5.0,
    "handover_stability": 5.0,
    "food_identification": 15.0,
}
"""How long the monitor waits without news, once it has seen every trial, before it ends the
graph. A trial's estimate lags its ground truth by the post-contact window (0.25 s for taps and
handovers, 3 s for food) plus processing; under load on two cores the food estimate outlasted a
5 s wait, so food waits longer."""


def _monitor_nodes(task: str, args: Mapping[str, str]) -> tuple[NodeSpec, ...]:
    if not as_bool(args["monitor"]):
        return ()
    trials = int(args["trials"])
    return (
        NodeSpec(
            package="ext_sense",
            executable="estimate_monitor",
            name="estimate_monitor",
            plugin="ext_sense.nodes.estimate_monitor:EstimateMonitorNode",
            parameters={
                "task": task,
                "expected": trials,
                "idle_timeout_s": MONITOR_IDLE_TIMEOUT_S[task],
            },
            remappings=(
                ("contact_estimate", TOPIC_ESTIMATE),
                ("ground_truth", TOPIC_GROUND_TRUTH),
            ),
            required=trials > 0,
        ),
    )


def _behaviour(
    executable: str,
    plugin_class: str,
    parameters: Mapping[str, ParameterValue] | None = None,
    remappings: tuple[tuple[str, str], ...] = (("contact_estimate", TOPIC_ESTIMATE),),
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
            remappings=(("contact_estimate", TOPIC_ESTIMATE), ("marker", TOPIC_TAP_MARKER)),
        ),
    )


SIM_TRIGGERS = {
    "handover_stability": (TOPIC_HANDOVER_OFFER, "start"),
    "food_identification": (TOPIC_MOTION_START, "onset"),
}
"""behaviours:=true with source sim: the topic on which each task's behaviour drives the
simulated device, and how a trial is aligned to it (a grasp starts when the object is offered;
a food trial's motion start is put at the probe's)."""

SIM_FOOD_ARM = {"start_z_m": 0.16, "surface_z_m": 0.152}
"""The simulated arm (``sim_arm``, franka_ros2's interfaces) against the food scene
(``food_fork_nuskin``): the tines touch the food 8 mm below the start (the scene draws 4..12 mm);
its force is a 1000 N/m spring, not the scene's per-food profile."""

SIM_FOOD_STOP_HEIGHT_M = 0.125
"""The probe's preset stop over the simulated arm: the scene's 35 mm travel from the start."""


def _handover_behaviours(args: Mapping[str, str]) -> tuple[NodeSpec, ...]:
    handover: dict[str, ParameterValue] = {"timeout_s": float(args["handover_timeout_s"])}
    if args["source"] == "sim":
        # the next simulated person's grasp after each handover, offered once the simulated
        # device listens, and not before the inference node has had time to load its model (as
        # the bag player's start delay)
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
            remappings=(
                ("contact_estimate", TOPIC_ESTIMATE),
                ("handover/offer", TOPIC_HANDOVER_OFFER),
            ),
        ),
    )


def _food_behaviours(args: Mapping[str, str]) -> tuple[NodeSpec, ...]:
    # the behaviour always drives the arm through the franka_ros2 adapter; with arm:=sim the
    # sim_arm node serves the same interfaces a franka_ros2 robot does
    food: dict[str, ParameterValue] = {"arm": "franka"}
    arm: tuple[NodeSpec, ...] = ()
    if args["arm"] == "sim":
        food["stop_height_m"] = SIM_FOOD_STOP_HEIGHT_M
        plugin = "ext_sense_sim.nodes.sim_arm:SimArmNode"
        arm = (NodeSpec("ext_sense_sim", "sim_arm", "sim_arm", plugin, dict(SIM_FOOD_ARM)),)
    if args["source"] == "sim":
        # probe by itself, once the window node and the simulated device hear the motion start
        food |= {"auto_start": True, "repeat_s": 2.0, "start_subscribers": 2}
    probe = _behaviour(
        "food_behaviour",
        "FoodBehaviourNode",
        food,
        remappings=(("contact_estimate", TOPIC_ESTIMATE), ("motion_start", TOPIC_MOTION_START)),
    )
    return (*arm, probe)


def _chain(
    task: str, behaviours: Callable[[Mapping[str, str]], tuple[NodeSpec, ...]]
) -> Callable[[Mapping[str, str]], tuple[NodeSpec, ...]]:
    """The build function of a task's graph: source, driver, perception, behaviours, monitor."""

    def build(args: Mapping[str, str]) -> tuple[NodeSpec, ...]:
        return place_hot_path(
            _source_nodes(task, args)
            + _perception_nodes(task, args)
            + (behaviours(args) if as_bool(args["behaviours"]) else ())
            + _monitor_nodes(task, args)
            + view_nodes(args, _sensor_topic(args["sensor"])),
            args,
        )

    return build


GRAPHS: dict[str, GraphSpec] = {
    "tap_localization": GraphSpec(
        name="tap_localization",
        description="Where was the held rod tapped? Tap position on /extsense/contact_estimate.",
        arguments=_common_arguments("30"),
        build=_chain("tap_localization", _tap_behaviours),
        files=_needed_files("tap_localization"),
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
        files=_needed_files("handover_stability"),
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
        files=_needed_files("food_identification"),
    ),
}
