"""``ext-sense record``, ``replay``, ``bag recover|migrate``: rosbag2 without the ``ros2`` CLI."""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path
from typing import TYPE_CHECKING, Any

from ext_sense.offline_replay import bag_task_sensor, offline_estimates

if TYPE_CHECKING:  # imported by the handlers: ``ext-sense --help`` stays fast
    from ext_sense.graph import NodeSpec
    from ext_sense_runtime.records import Estimate


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``record`` and ``replay`` subcommands."""
    rec = subparsers.add_parser(
        "record",
        help="record ext_sense topics into a rosbag2 (mcap) bag",
        description="Record topics into a new rosbag2 bag (raw CDR bytes, correct type hashes).",
    )
    rec.add_argument("out", type=Path, help="directory of the new bag (must not exist)")
    rec.add_argument(
        "--topics",
        nargs="+",
        help="topics to record (default: every ext_sense topic and /diagnostics)",
    )
    rec.add_argument("--storage", choices=("mcap", "sqlite3"), default="mcap")
    rec.add_argument(
        "--duration", type=float, default=0.0, help="stop after S seconds (default: until Ctrl-C)"
    )
    rec.add_argument(
        "--flush-period",
        type=float,
        default=1.0,
        metavar="S",
        help="write to the disk at least every S seconds: what a killed recorder loses (default 1)",
    )
    rec.set_defaults(func=_record)

    bag = subparsers.add_parser(
        "bag",
        help="bag tools: recover a bag a killed recorder left, migrate one of decoded arrays",
        description="Bag tools (rosbag2, mcap or sqlite3).",
    )
    bag_sub = bag.add_subparsers(dest="bag_command", metavar="ACTION")
    bag_sub.required = True
    rcv = bag_sub.add_parser(
        "recover",
        help="rewrite every complete message of a crashed recording as a complete bag",
        description="Write every complete message of a bag whose recorder was killed into a "
        "complete bag with metadata.yaml; print what was recovered and dropped. In place by "
        "default (the original is renamed BAG.damaged); a complete bag is left alone.",
    )
    rcv.add_argument("bag", type=Path, help="bag directory or .mcap/.db3 file")
    rcv.add_argument(
        "--out", type=Path, help="write the recovered bag here instead (must not exist)"
    )
    rcv.set_defaults(func=_bag_recover)
    mig = bag_sub.add_parser(
        "migrate",
        help="rewrite a bag of decoded arrays (recorded before packets) as a packet bag",
        description="Rewrite a bag recorded before the drivers published raw packets as the "
        "packet bag the graphs replay: its events or frames encoded again with the drivers' "
        "encoders (the sensor's own bytes are not in it), every other topic copied.",
    )
    mig.add_argument("bag", type=Path, help="bag directory or .mcap/.db3 file to read")
    mig.add_argument("out", type=Path, help="directory of the new packet bag (must not exist)")
    mig.set_defaults(func=_bag_migrate)

    rep = subparsers.add_parser(
        "replay",
        help="play a bag into the graph, or run the graph's core on it offline",
        usage="ext-sense replay [-h] [options] BAG [view:=true view_port:=N ...]",
        description="Publish a bag's sensor packets and ground truth (recorded pace or flat "
        "out), or with --offline run windowing and the model on it deterministically. "
        "view:=true (view_host, view_port, view_rate as for `ext-sense run`) also starts the "
        "live Foxglove view, plays what it reads and keeps it up until Ctrl-C (docs/view.md).",
    )
    rep.add_argument("bag", type=Path, help="bag directory or .mcap/.db3 file")
    pace = rep.add_mutually_exclusive_group()
    pace.add_argument("--rate", type=float, default=1.0, help="playback speed (1.0 recorded)")
    pace.add_argument("--flat-out", action="store_true", help="publish as fast as possible")
    rep.add_argument(
        "--topics",
        nargs="+",
        help="topics to publish (default: the graph inputs in the bag; 'all' for every topic)",
    )
    rep.add_argument("--start-delay", type=float, default=1.0, help="wait for subscribers, s")
    rep.add_argument(
        "--offline",
        action="store_true",
        help="no ROS: run windowing and the model on the bag directly (deterministic)",
    )
    rep.add_argument("--task", default="", help="offline: task (default: from the bag)")
    rep.add_argument(
        "--sensor", default="", help="offline and view:=true: sensor (default: from the bag)"
    )
    rep.add_argument(
        "--model",
        default="",
        help="offline: model bundle directory, or a model name looked up as the graphs do "
        "(default: the task's default model, <task>_<sensor>; `ext-sense models list`)",
    )
    rep.add_argument("--backend", choices=("onnx", "sklearn"), default="onnx")
    rep.add_argument("--json", type=Path, help="offline: write every estimate to this file")
    rep.add_argument("--quiet", action="store_true", help="offline: only the summary")
    rep.set_defaults(func=_replay, accepts_assignments=True)


def _record(args: argparse.Namespace) -> int:
    """Record until a stop signal (exit 0), ``--duration`` or a write failure (exit 1)."""
    from rclpy.parameter import Parameter

    from ext_sense.nodes.recorder import RecorderNode
    from ext_sense_bags import BagError
    from ext_sense_runtime.node_main import RosSession

    overrides = [
        Parameter("bag", value=str(args.out)),
        Parameter("storage", value=args.storage),
        Parameter("flush_period_s", value=float(args.flush_period)),
    ]
    if args.topics:
        overrides.append(Parameter("topics", value=list(args.topics)))
    try:
        with RosSession(args=[]) as ros:
            node = ros.add(RecorderNode(parameter_overrides=overrides))
            if node.failed:  # the bag could not be created
                print(f"ext-sense record: {node.failed}", file=sys.stderr)
                return 2
            print(f"recording {sorted(node.received)} into {args.out} (Ctrl-C stops)", flush=True)
            end = time.monotonic() + args.duration if args.duration > 0 else float("inf")
            ros.spin(until=lambda: bool(node.failed) or time.monotonic() >= end)
            counts = dict(node.received)
            ros.close()  # destroys the node: the bag is closed
    except BagError as err:
        print(f"ext-sense record: {err}", file=sys.stderr)
        return 2
    done, rc = "recorded", 0
    if node.failed:  # a write failed (disk full, ...): said once, exit 1
        print(f"ext-sense record: recording stopped: {node.failed}", file=sys.stderr)
        done, rc = "received before the failure", 1
    print(f"{done} {sum(counts.values())} messages: {counts}", flush=True)
    return rc


def _bag_recover(args: argparse.Namespace) -> int:
    from ext_sense_bags.recover import BagError, bag_problem, recover_bag

    try:
        problem = bag_problem(args.bag)
        if not problem:
            print(f"{args.bag} is complete: nothing to recover", flush=True)
            return 0
        result = recover_bag(args.bag, args.out)
    except BagError as err:
        print(f"ext-sense bag recover: {err}", file=sys.stderr)
        return 2
    report = result.report
    print(f"{report.file}: {report.problem or problem}")
    print(f"recovered {result.messages} messages into {result.out}:")
    for topic, n in sorted(result.counts.items()):
        print(f"  {topic}: {n}")
    if report.storage == "mcap":
        print(
            f"dropped: {report.chunks_dropped} chunks, {report.bytes_dropped} bytes "
            f"({report.chunks} complete chunks read)"
        )
    else:
        print("dropped: the uncommitted last transaction (SQLite recovery keeps every commit)")
    if report.orphans:
        print(f"dropped: {report.orphans} messages whose channel record was lost")
    if result.skipped_topics:
        print(f"not rewritten (no definition or type hash): {list(result.skipped_topics)}")
    if result.kept is not None:
        print(f"the damaged original is kept at {result.kept}")
    return 0


def _bag_migrate(args: argparse.Namespace) -> int:
    from ext_sense.bag_migrate import migrate_bag
    from ext_sense_bags import BagError

    try:
        done = migrate_bag(args.bag, args.out)
    except BagError as err:
        print(f"ext-sense bag migrate: {err}", file=sys.stderr)
        return 2
    print(f"wrote {done.out}:")
    for topic, n in sorted(done.packets.items()):
        print(f"  {topic}: {n} packets ({done.events} events, {done.frames} frames re-encoded)")
    for topic, n in sorted(done.copied.items()):
        print(f"  {topic}: {n} copied")
    return 0


def _replay(args: argparse.Namespace) -> int:
    from ext_sense.graph import GraphError
    from ext_sense_bags import BagError

    try:
        if args.offline:
            if args.assignments:
                raise GraphError(
                    f"--offline starts no node: {' '.join(args.assignments)} is for a live replay."
                )
            return _replay_offline_cli(args)
        return _replay_live(args, _replay_view(args))
    except (BagError, GraphError) as err:
        print(f"ext-sense replay: {err}", file=sys.stderr)
        return 2


def _replay_view(args: argparse.Namespace) -> NodeSpec | None:
    """The ``foxglove_view`` node that ``view:=true`` asks for, else ``None``."""
    from ext_sense.graph import GraphError, as_bool, parse_assignments
    from ext_sense.topics import SENSOR_PACKETS
    from ext_sense.view.graph import replay_view_graph

    overrides = parse_assignments(args.assignments)
    # the arguments are checked before the bag is read (the sensor does not change them)
    if not as_bool(replay_view_graph("nuskin").resolve(overrides)["view"]):
        return None
    sensor = args.sensor or bag_task_sensor(args.bag)[1]
    if sensor not in SENSOR_PACKETS:
        raise GraphError(f"--sensor must be one of {', '.join(SENSOR_PACKETS)}. Got '{sensor}'.")
    return replay_view_graph(sensor).nodes(overrides)[0]


def _replay_live(args: argparse.Namespace, view: NodeSpec | None = None) -> int:
    """Play the bag; with ``view`` also run the view in its own process, up until Ctrl-C."""
    import subprocess

    from rclpy.parameter import Parameter

    from ext_sense.nodes.bag_player import BagPlayerNode
    from ext_sense.offline_replay import packet_topic
    from ext_sense.runner import exit_status, spawn_node, stop_nodes
    from ext_sense.view.channels import view_inputs
    from ext_sense_bags import BagReader
    from ext_sense_runtime.node_main import RosSession

    rate = 0.0 if args.flat_out else float(args.rate)
    overrides = [
        Parameter("bag", value=str(args.bag)),
        Parameter("rate", value=rate),
        Parameter("start_delay_s", value=float(args.start_delay)),
    ]
    topics = list(args.topics or ())
    if view is not None and not topics:  # what the view reads: the session as recorded
        sensor = str(view.parameters["sensor"])
        with BagReader(args.bag) as reader:
            packet_topic(reader.topics, args.bag, sensor)  # BagError: no packets to decode
        topics = list(view_inputs(sensor))
    if topics:
        overrides.append(Parameter("topics", value=topics))
    procs: dict[str, subprocess.Popen[bytes]] = {}
    rc = 0

    def view_gone() -> bool:
        return any(p.poll() is not None for p in procs.values())

    with RosSession(args=[]) as ros:
        try:
            if view is not None:
                procs[view.name] = spawn_node(view, use_sim_time=False)
                where = f"ws://{view.parameters['host']}:{view.parameters['port']}"
                if view.parameters["port"] == 0:
                    where += " (any free port: the view's log names it)"
                print(f"[replay] started {view.name}: the Foxglove view on {where}", flush=True)
            node = ros.add(BagPlayerNode(parameter_overrides=overrides))
            ros.spin(until=lambda: node.finished.is_set() or view_gone(), timeout_s=0.05)
            if ros.stop.requested() or view_gone():
                why = ": the view exited" if view_gone() and not ros.stop.requested() else ""
                print(f"stopped after {node.published} messages{why}", flush=True)
            elif node.error:
                print(f"ext-sense replay: {node.error}", file=sys.stderr)
                rc = 2
            else:
                seconds = max(node.play_seconds, 1e-9)
                print(
                    f"published {node.published} messages in {seconds:.3f} s "
                    f"({node.published / seconds:.0f} msg/s)",
                    flush=True,
                )
                if procs:
                    print("[replay] the bag is played; the view stays up until Ctrl-C", flush=True)
                    ros.spin(until=view_gone)
        finally:
            codes = stop_nodes(procs, sys.stderr)
    for name, code in codes.items():
        if code != 0:
            print(f"ext-sense replay: {name} exited with {code}", file=sys.stderr)
            rc = rc or exit_status(code)
    return rc


def _replay_offline_cli(args: argparse.Namespace) -> int:
    from ext_sense.nodes.scoreboard import Scoreboard
    from ext_sense_perception.errors import PerceptionError
    from ext_sense_perception.online.model_store import find_model
    from ext_sense_perception.online.predictor import load_model
    from ext_sense_perception.online.window import WindowConfig
    from ext_sense_runtime.records import truth_of

    task, sensor = args.task, args.sensor
    if not (task and sensor):
        guessed = bag_task_sensor(args.bag)
        task, sensor = task or guessed[0], sensor or guessed[1]
    try:
        model_dir = find_model(args.model, task, sensor)
        model = load_model(model_dir, args.backend)
        if (model.task, model.card.sensor) != (task, sensor):
            raise PerceptionError(
                f"The model in {model_dir} is for {model.task}/{model.card.sensor}; the bag is "
                f"{task}/{sensor}."
            )
        config = WindowConfig(model.card.profile, sensor)  # the windows the model was made for
        replay = list(offline_estimates(args.bag, config, model))
    except PerceptionError as err:
        print(f"ext-sense replay: {err}", file=sys.stderr)
        return 2
    board = Scoreboard(task)
    estimates: list[Estimate] = []
    rejected = 0
    for kind, item in replay:
        if kind == "truth":
            lines = board.add_truth(truth_of(item))
        elif kind == "rejected":
            rejected += 1
            lines = [f"window rejected: {item}"]
        else:
            estimates.append(item)
            lines = board.add_estimate(item)
        if not args.quiet:
            for line in lines:
                print(line)
    board.close()
    if args.json:
        args.json.write_text(json.dumps([_jsonable(e) for e in estimates], indent=1))
    if rejected:
        print(f"windows rejected: {rejected}")
    print(board.summary(), flush=True)
    return 0


def _jsonable(est: Estimate) -> dict[str, Any]:
    """An estimate as JSON values (NaN as null), with ``stamp_ns`` for its onset."""
    out: dict[str, Any] = {"stamp_ns": est.onset_ns}
    for key, value in est._asdict().items():
        if key == "onset_ns":
            continue
        if isinstance(value, tuple):
            value = list(value)
        if isinstance(value, float) and value != value:  # NaN is not JSON
            value = None
        out[key] = value
    return out
