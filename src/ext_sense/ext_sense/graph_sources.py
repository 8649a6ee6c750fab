"""Where a graph's sensor data comes from: the simulated device or bag player, and the driver.

Called by :mod:`ext_sense.graphs`' build functions: the four sources (``sim``, ``serial``,
``can``, ``bag``) and the files they need. Every source feeds the sensor's raw packets.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Mapping
from pathlib import Path

from ext_sense.graph import ArgumentSpec, GraphError, NodeSpec, ParameterValue, as_bool
from ext_sense.topics import (
    SENSOR_PACKETS,
    TOPIC_GROUND_TRUTH,
    TOPIC_HANDOVER_OFFER,
    TOPIC_MOTION_START,
)
from ext_sense_perception.profiles import profile_for
from ext_sense_sim.scene import DEFAULT_SCENES as DEFAULT_SCENES

STARTUP_SPARE_TRIALS = 3
"""Extra simulated trials: those streamed while the graph is still starting are lost."""
MONITOR_WAIT_S = 60.0
"""How long the simulated device waits for the monitor before its first trial, s (discovery
under load can take seconds)."""
MONITOR_NODE = "estimate_monitor"
"""The monitor's node name: the subscriber to ground truth the simulated device waits for."""

SIM_TRIGGERS = {
    "handover_stability": (TOPIC_HANDOVER_OFFER, "start"),
    "food_identification": (TOPIC_MOTION_START, "onset"),
}
"""behaviours:=true with source sim: the topic on which each task's behaviour drives the
simulated device, and how a trial is aligned to it."""

PACKET_ARGUMENTS: tuple[ArgumentSpec, ...] = (
    ArgumentSpec(
        "reader_priority",
        "50",
        "SCHED_FIFO priority of the sensor driver's reader thread (its drain thread 10 below), "
        "1-99; 0 leaves the scheduling as is. Needs CAP_SYS_NICE or an rtprio limit "
        "(docs/runtime.md, 'Real-time priority for the reader'); refused, the driver falls "
        "back to nice -10 or normal priority and says so.",
        kind=int,
        low=0,
        high=99,
    ),
)


def _check_packets(bag: Path, sensor: str) -> None:
    """Refuse a bag with no packets of ``sensor`` (one of decoded arrays: ``bag migrate``).

    Raises:
        GraphError: The bag cannot be read, or holds no ``SensorPacket`` of the sensor.
    """
    from ext_sense.offline_replay import packet_topic
    from ext_sense_bags import BagError, BagReader

    try:
        with BagReader(bag) as reader:
            packet_topic(reader.topics, bag, sensor)
    except (BagError, OSError) as err:
        raise GraphError(f"The 'bag' argument: {err}") from err


def port_path(task: str, args: Mapping[str, str]) -> str:
    """The sensor's serial device, or where the simulated device links its pty."""
    return args["port"] or f"/tmp/ext_sense_{task}_{args['sensor']}.pty"


def needed_files(task: str) -> Callable[[Mapping[str, str]], None]:
    """The graph's check of the files its source needs (a serial device is not: it may come)."""

    def check(args: Mapping[str, str]) -> None:
        source, bag, scene = args["source"], args["bag"], args["scene"]
        if source == "bag" and not (bag and Path(bag).exists()):
            got = f"'{bag}': no such file or directory" if bag else "nothing"
            raise GraphError(
                f"The 'bag' argument must name an existing rosbag2 directory or .mcap/.db3 file "
                f"with source:=bag. Got {got}."
            )
        if source == "bag":
            _check_packets(Path(bag), args["sensor"])
        if source != "sim":
            return
        if not args["can_channel"]:
            port = Path(port_path(task, args))
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


def source_nodes(task: str, args: Mapping[str, str]) -> tuple[NodeSpec, ...]:
    """The device emulator or bag player, and the driver."""
    sensor, source = args["sensor"], args["source"]
    packets = ("packets", SENSOR_PACKETS[sensor])
    nodes: list[NodeSpec] = []
    if source == "bag":
        return (
            NodeSpec(
                package="ext_sense",
                executable="bag_player",
                name="bag_player",
                plugin="ext_sense.nodes.bag_player:BagPlayerNode",
                # start_delay_s: let inference load its model before the first trial
                parameters={"bag": args["bag"], "rate": 1.0, "start_delay_s": 4.0},
                remappings=(packets, ("ground_truth", TOPIC_GROUND_TRUTH)),
            ),
        )
    over_can = source == "can" or (source == "sim" and bool(args["can_channel"]))
    if source == "sim":
        trials = int(args["trials"])
        # trials streamed before the driver has the port are lost: spare ones keep N scored
        stream: dict[str, ParameterValue] = {
            "trials": trials + STARTUP_SPARE_TRIALS if trials > 0 else 0
        }
        if as_bool(args["monitor"]):  # no trial before the monitor can hear its estimate
            stream["wait_for_listener_s"] = MONITOR_WAIT_S
            stream["listener_node"] = MONITOR_NODE  # not a view or recorder listening first
        # a trial within the task's debounce of the last would be one contact with it (food:
        # 8 s, longer than a 6.5 s trial, so every other trial was lost)
        stream["trial_period_s"] = max(1.0, profile_for(task).debounce_ns / 1e9 + 0.5)
        remaps: tuple[tuple[str, str], ...] = (("ground_truth", TOPIC_GROUND_TRUTH),)
        if as_bool(args["behaviours"]) and task in SIM_TRIGGERS:
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
                    "port_link": port_path(task, args),
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
                "port": port_path(task, args),
                "baud": int(args["baud"]),
                "can_interface": "virtual" if source == "sim" else args["can_interface"],
                "can_channel": args["can_channel"],
                **(
                    {"frame_id": "nuskin"} if sensor == "nuskin" else {"frame_id_prefix": "biotac_"}
                ),
                "autostart": False,
                # the emulated devices are silent between trials: no stall check on them
                **({"expected_rate_hz": 0.0} if source == "sim" else {}),
                "reader_priority": int(args["reader_priority"]),
            },
            remappings=(packets,),
            lifecycle=True,
            manage=as_bool(args["manage_drivers"]),
        )
    )
    return tuple(nodes)
