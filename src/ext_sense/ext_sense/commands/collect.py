"""``ext-sense collect TASK OUT``: guided recording of one labelled session on a live graph.

Starts the task's graph rewired (:mod:`ext_sense.collect.graph`), records into one mcap bag at
``OUT`` with :class:`~ext_sense.collect.node.CollectorNode`, asks the operator (or ``--answers``)
about each trial, and writes the kept labels when the session ends. See docs/collect.md.
"""

from __future__ import annotations

import argparse
import dataclasses
import datetime as dt
import shutil
import sys
from pathlib import Path
from typing import Any, NamedTuple

from ext_sense.collect.session import (
    FOOD_CLASSES,
    GRAPH_OF_TASK,
    HANDOVER_CLASSES,
    TASKS,
    Answers,
    CollectError,
    CollectState,
    class_sequence,
    read_answers,
    sim_schedule,
    tap_sequence,
    window_note,
)
from ext_sense.topics import SENSOR_PACKETS

FOOD_WINDOW_END_S = 8.0
"""The food behaviour's ``window_end_s`` when the graph does not set it (its default)."""


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``collect`` subcommand."""
    p = subparsers.add_parser(
        "collect",
        help="record one labelled session on a live graph (guided or scripted)",
        description="Guided recording of one labelled session into one mcap bag (the sensor "
        "stream, arm and gripper state, labels as ContactGroundTruth) with session.json. "
        "Graph arguments (name:=value) go to the task's graph, as with ext-sense run.",
    )
    p.add_argument("task", choices=TASKS)
    p.add_argument("out", type=Path, help="session directory = the new bag's directory")
    p.add_argument("--trials", type=int, default=10, help="trials to keep (default 10)")
    p.add_argument("--answers", type=Path, help="scripted mode: one answer per prompt")
    p.add_argument("--resume", action="store_true", help="continue the session in OUT")
    p.add_argument("--seed", type=int, default=0, help="seed of the prompt sequence")
    p.add_argument("--classes", default="", help="label set, comma separated (food)")
    p.add_argument("--tap-range", default="0.05,0.28", help="rod's marked range, m: LOW,HIGH")
    p.add_argument("--rod-length", type=float, default=0.30, help="tap: rod length, m")
    p.add_argument(
        "--truth",
        choices=("prompt", "sim", "mocap"),
        default="",
        help="tap labels from the prompt, the simulator's truth, or --mocap-topic "
        "(default: sim with source:=sim, else prompt)",
    )
    p.add_argument("--mocap-topic", default="", help="geometry_msgs/PoseStamped of the tap point")
    for name in ("name", "date", "sensor-id", "robot", "notes", "baseline"):
        p.add_argument(f"--{name}", default="", help=f"session metadata: {name}")
    p.set_defaults(func=_collect, accepts_assignments=True)


def _plan(args: argparse.Namespace, classes: tuple[str, ...]) -> list[str]:
    if args.task == "tap_localization":
        low, high = (float(x) for x in args.tap_range.split(","))
        return [f"{x:.3f}" for x in tap_sequence(args.trials, low, high, args.seed)]
    return class_sequence(classes, args.trials, args.seed)


class _Graph(NamedTuple):
    """The graph as collect runs it."""

    name: str
    nodes: list[Any]
    source: str
    model: str
    sim_trigger: bool
    """Scripted handover on the simulator: collect triggers each simulated grasp."""


def _graph_nodes(args: argparse.Namespace, schedule: list[str], scripted: bool) -> _Graph:
    """The graph's nodes, changed for collecting (:func:`ext_sense.collect.graph.collect_nodes`)."""
    from ext_sense.collect.graph import collect_nodes
    from ext_sense.graph import parse_assignments
    from ext_sense.graph_model import with_model
    from ext_sense.graphs import GRAPHS

    graph = GRAPHS[GRAPH_OF_TASK[args.task]]
    overrides = parse_assignments(args.assignments)
    overrides.setdefault("monitor", "false")
    overrides.setdefault("trials", "0")
    simulated = overrides.get("source", "sim") == "sim"
    if args.task != "tap_localization":
        overrides.setdefault("behaviours", "true")
        if schedule and simulated:
            overrides.setdefault("sim_labels", ",".join(schedule))
    if args.task == "handover_stability":
        overrides.setdefault("grasp_trials", "2")
        overrides.setdefault("handover_timeout_s", "6")
    overrides = with_model(graph, overrides)
    values = graph.resolve(overrides)
    sim = values["source"] == "sim"
    trigger = sim and scripted and args.task == "handover_stability"
    nodes = collect_nodes(args.task, graph.build(values), sim, sim_trigger=trigger)
    return _Graph(graph.name, nodes, values["source"], values["model"], trigger)


def _food_note(graph: _Graph) -> str:
    """Why a food probe of this graph can show no live estimate (``""``: the window fits)."""
    from ext_sense_perception.errors import PerceptionError
    from ext_sense_perception.online.model_card import read_card

    probe = next((s for s in graph.nodes if s.executable == "food_behaviour"), None)
    if probe is None:
        return ""
    try:
        model_end_ns = read_card(graph.model).profile.post_ns
    except PerceptionError:
        return ""
    probe_end_s = float(probe.parameters.get("window_end_s", FOOD_WINDOW_END_S))
    return window_note(model_end_ns, round(probe_end_s * 1e9))


def _collect(args: argparse.Namespace) -> int:
    try:
        return _run(args)
    except CollectError as err:
        print(f"ext-sense collect: {err}", file=sys.stderr)
        return 2


def _run(args: argparse.Namespace) -> int:
    from ext_sense.collect.loop import TrialLoop
    from ext_sense.collect.node import CollectorNode
    from ext_sense.graph import GraphError
    from ext_sense.runner import spawn_node, stop_nodes
    from ext_sense_bags import BagError
    from ext_sense_runtime.node_main import RosSession

    out: Path = args.out
    classes = tuple(c for c in args.classes.split(",") if c) or (
        HANDOVER_CLASSES if args.task == "handover_stability" else FOOD_CLASSES
    )
    if args.resume:
        state = CollectState.load(out)
        if state.task != args.task:
            raise CollectError(f"{out} is a {state.task} session, not {args.task}.")
    elif out.exists():
        raise CollectError(f"{out} exists: give a new directory, or --resume to continue it.")
    else:
        state = CollectState(args.task, _plan(args, classes))
    scripted = read_answers(args.answers) if args.answers else None
    schedule = sim_schedule(args.task, scripted, classes) if scripted is not None else []
    try:
        graph = _graph_nodes(args, schedule, scripted is not None)
    except GraphError as err:
        raise CollectError(str(err)) from err
    source, nodes = graph.source, graph.nodes
    truth_mode = args.truth or ("mocap" if args.mocap_topic else "sim" if source == "sim" else "")
    truth_mode = truth_mode or "prompt"
    sensor = next(s.parameters.get("sensor") for s in nodes if "sensor" in s.parameters)
    stream = SENSOR_PACKETS[str(sensor)]
    try:
        writer = _open_bag(out, args.resume)
    except BagError as err:
        raise CollectError(str(err)) from err
    writer.set_custom_data("task", args.task)
    writer.set_custom_data("sensor", str(sensor))
    writer.set_custom_data("recorded_by", "ext-sense collect")
    _write_info(args, out, str(sensor), classes)
    # callbacks in a thread of their own; a stop signal interrupts the prompt, the session is saved
    ros = RosSession(args=[], interrupt=True)
    node = ros.add(CollectorNode(writer, stream, args.mocap_topic if truth_mode == "mocap" else ""))
    procs: dict[str, Any] = {}
    rc = 0
    gripper = _sim_gripper(nodes) if source == "sim" else None
    try:
        ros.spin_in_background()
        for spec in nodes:
            procs[spec.name] = spawn_node(spec, False)
        print(f"[collect] graph {graph.name} ({source}); {len(state.trials)} trials kept so far")
        loop = TrialLoop(
            node,
            state,
            out,
            Answers(scripted),
            truth_mode,
            classes,
            sim=source == "sim",
            sim_trigger=graph.sim_trigger,
            food_note=_food_note(graph),
        )
        {
            "tap_localization": loop.tap,
            "handover_stability": loop.handover,
            "food_identification": loop.food,
        }[args.task]()
    except KeyboardInterrupt:
        rc = ros.stop.exit_code() if ros.stop.requested() else 130
    finally:
        stop_nodes(procs, sys.stderr)
        if gripper is not None:
            gripper.__exit__(None, None, None)
        for trial in state.trials:
            for onset in trial.onsets_ns:
                node.write_label(args.task, trial.index, onset, trial.label, args.rod_length)
        ros.close()
        writer.close()
        state.save(out)
    print(f"[collect] {state.progress()}; session in {out}", flush=True)
    if not state.done:
        print(f"[collect] unfinished: continue with --resume ({out})", flush=True)
    return rc


EMULATED_OBJECT_POSITION = 128
"""Where the emulated Robotiq's fingers meet the simulated object (0..255)."""


def _sim_gripper(nodes: list[Any]) -> Any:
    """A Robotiq emulated on a pty for a gripper node with no ``port``; None when none."""
    from ext_sense_sim.devices.robotiq_emulator import GripperModel, PtyGripper, RobotiqEmulator

    spec = next((s for s in nodes if s.executable == "robotiq_gripper"), None)
    if spec is None or spec.parameters.get("port"):
        return None
    model = GripperModel(activation_s=0.05, object_position=EMULATED_OBJECT_POSITION)
    pty = PtyGripper(RobotiqEmulator(model)).__enter__()
    nodes[nodes.index(spec)] = dataclasses.replace(
        spec, parameters={**spec.parameters, "port": pty.path}
    )
    return pty


def _open_bag(out: Path, resume: bool) -> Any:
    """A new bag at ``out``; on resume the old one's messages but labels are copied first."""
    from ext_sense_bags import BagReader, BagWriter

    if not resume:
        return BagWriter(out, flush_period_s=1.0).open()
    old = out.with_name(out.name + ".resumed")
    if old.exists():
        shutil.rmtree(old)
    out.rename(old)
    writer = BagWriter(out, flush_period_s=1.0).open()
    with BagReader(old) as bag:
        for rec in bag.records():
            if rec.topic == "/extsense/ground_truth":
                continue
            if not writer.msgtype(rec.topic):
                writer.add_topic(rec.topic, rec.msgtype)
            writer.write_raw(rec.topic, rec.log_time_ns, bag.current_cdr(rec))
    for name in ("collect.json", "session.json"):
        if (old / name).is_file():
            shutil.copy(old / name, out / name)
    shutil.rmtree(old)
    return writer


def _write_info(args: argparse.Namespace, out: Path, sensor: str, classes: tuple) -> None:
    from ext_sense_perception.data.sessions import SessionInfo, read_info, write_info

    previous = read_info(out) if args.resume else None
    info = previous or SessionInfo(
        name=args.name or out.name,
        date=args.date or dt.date.today().isoformat(),
        sensor=sensor,
        sensor_id=args.sensor_id,
        robot=args.robot,
        labels=() if args.task == "tap_localization" else tuple(classes),
        notes=args.notes,
        baseline=args.baseline,
    )
    write_info(out, info)
