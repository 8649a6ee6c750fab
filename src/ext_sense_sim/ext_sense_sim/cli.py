"""``ext-sense sim list|run|fidelity|calibrate|serve``: the simulator's subcommands."""

from __future__ import annotations

import argparse
import sys


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add ``sim`` and its subcommands to the ``ext-sense`` parser."""
    sim = subparsers.add_parser("sim", help="scene simulator and emulated devices")
    sub = sim.add_subparsers(dest="sim_command", metavar="SIM_COMMAND")
    sub.required = True

    p = sub.add_parser("list", help="name the shipped scenes")
    p.set_defaults(func=_list)

    p = sub.add_parser("run", help="simulate a scene and write its datasets")
    p.add_argument("scene", help="shipped scene name or path of a scene YAML file")
    p.add_argument("--out", required=True, help="output folder")
    p.add_argument("--trials", type=int, default=None, help="number of trials (scene default)")
    p.add_argument("--seed", type=int, default=None, help="seed (scene default)")
    p.add_argument(
        "--formats",
        default="npz,paper,raw,bag",
        help="comma-separated outputs among npz, paper, raw, bag (default: all)",
    )
    p.set_defaults(func=_run)

    p = sub.add_parser(
        "fidelity",
        help="compare a scene with real NUSkin captures (taps, food)",
        description=(
            "Simulate a NUSkin tap or food scene and compare it with real captures at their "
            "own 10 ms time resolution: statistics per real session and pooled, issue 30's "
            "targets, a classifier two-sample test (docs/simulator.md)."
        ),
    )
    _scene_and_real(p)
    p.add_argument("--trials", type=int, default=None, help="simulated trials (taps 60, food 35)")
    p.add_argument("--seed", type=int, default=None, help="seed (scene default)")
    p.add_argument("--json", default=None, metavar="PATH", help="also write the result as JSON")
    p.add_argument("--figure", default=None, metavar="PATH", help="also draw the figure (PNG)")
    p.add_argument(
        "--check", action="store_true", help="exit 1 when a tap target fails (for scripts)"
    )
    p.set_defaults(func=_fidelity)

    p = sub.add_parser(
        "calibrate",
        help="fit a NUSkin tap or food scene's physics to real captures",
        description=(
            "Fit a scene's free physical parameters to real captures by a deterministic "
            "coordinate search (ext_sense_sim.calibration; docs/simulator.md, 'Calibration "
            "against the real sensor'): a tap scene's noise on the quiet stretch before each "
            "tap, then its tap, rod and grasp on the tap windows; a food scene's noise, "
            "resting readings, contact strip and grip on the trials after the motion start."
        ),
    )
    _scene_and_real(p)
    p.add_argument(
        "--stages",
        default=None,
        help="comma-separated stages among noise, taps, food (default: noise,taps for a tap "
        "scene, food for a food scene)",
    )
    p.add_argument("--trials", type=int, default=None, help="simulated trials per evaluation")
    p.add_argument("--seed", type=int, default=5, help="seed of every evaluation (default 5)")
    p.add_argument(
        "--evaluations", type=int, default=60, help="simulations per stage at most (default 60)"
    )
    p.add_argument(
        "--hold",
        default="",
        metavar="EFFECT.KEY,...",
        help="free parameters kept at the scene's value (e.g. a sensor property fitted on "
        "another scene: nuskin_transduction.refractory_s)",
    )
    p.add_argument("--out", default=None, metavar="PATH", help="write the fitted scene here")
    p.set_defaults(func=_calibrate)

    p = sub.add_parser("serve", help="emulate a device on a pty or CAN channel in real time")
    p.add_argument("device", choices=("nuskin", "biotac", "robotiq"))
    p.add_argument("--scene", default=None, help="scene name or file (nuskin, biotac)")
    p.add_argument("--can", default=None, metavar="CHANNEL", help="python-can virtual channel")
    p.add_argument("--trials", type=int, default=0, help="trials to stream (0 = forever)")
    p.add_argument("--seed", type=int, default=None, help="seed (scene default)")
    p.add_argument("--period", type=float, default=1.0, help="seconds between trial starts")
    p.add_argument("--link", default=None, help="also create this symlink to the pty")
    p.set_defaults(func=_serve)


def _scene_and_real(p: argparse.ArgumentParser) -> None:
    """The scene and the real sessions that ``fidelity`` and ``calibrate`` hold it against."""
    p.add_argument("scene", help="shipped scene name or path of a scene YAML file")
    p.add_argument(
        "--real",
        action="append",
        required=True,
        metavar="DIR",
        help="a real session: a day's rod-tap folder (or its rodNN/), or a food-poking "
        "folder; repeat for several sessions",
    )


def _list(args: argparse.Namespace) -> int:
    from ext_sense_sim.scene import load_scene, shipped_scenes

    for name in shipped_scenes():
        scene = load_scene(name)
        print(
            f"{name:28s} {scene.task.label:20s} {scene.sensor.label:7s} "
            f"{scene.geometry.kind}:{scene.geometry.length_m:g} m  {scene.description}"
        )
    return 0


def _run(args: argparse.Namespace) -> int:
    from ext_sense_sim.errors import SceneError
    from ext_sense_sim.run import run_scene
    from ext_sense_sim.scene import load_scene

    try:
        scene = load_scene(args.scene)
        formats = tuple(f.strip() for f in args.formats.split(",") if f.strip())
        summary = run_scene(scene, args.out, args.trials, args.seed, formats)
    except SceneError as err:
        print(f"ext-sense sim run: {err}", file=sys.stderr)
        return 2
    print(f"{summary['trials']} trials of {summary['scene']} in {summary['simulate_s']} s:")
    for name in summary["files"]:
        print(f"  {args.out}/{name}")
    return 0


def _fidelity(args: argparse.Namespace) -> int:
    from pathlib import Path

    from ext_sense_sim.errors import SceneError
    from ext_sense_sim.fidelity.check import result_json, run_fidelity
    from ext_sense_sim.fidelity.errors import FidelityError
    from ext_sense_sim.fidelity.figure import draw
    from ext_sense_sim.fidelity.table import format_table
    from ext_sense_sim.scene import load_scene

    try:
        if args.trials is not None and args.trials < 1:
            raise SceneError(f"--trials must be >= 1. Got {args.trials} instead.")
        run = run_fidelity(load_scene(args.scene), args.real, args.trials, args.seed)
    except (SceneError, FidelityError) as err:
        print(f"ext-sense sim fidelity: {err}", file=sys.stderr)
        return 2
    print(format_table(run.result))
    try:
        if args.json:
            Path(args.json).parent.mkdir(parents=True, exist_ok=True)
            Path(args.json).write_text(result_json(run.result))
            print(f"wrote {args.json}")
        if args.figure:
            print(f"wrote {draw(run, args.figure)}")
    except OSError as err:
        print(f"ext-sense sim fidelity: cannot write: {err}", file=sys.stderr)
        return 2
    return 1 if args.check and run.result["pass"] is False else 0


def _calibrate(args: argparse.Namespace) -> int:
    from pathlib import Path

    from ext_sense_sim.calibration import calibrate_scene
    from ext_sense_sim.errors import SceneError
    from ext_sense_sim.fidelity.errors import FidelityError
    from ext_sense_sim.scene import load_scene

    try:
        if args.trials is not None and args.trials < 1:
            raise SceneError(f"--trials must be >= 1. Got {args.trials} instead.")
        if args.evaluations < 1:
            raise SceneError(f"--evaluations must be >= 1. Got {args.evaluations} instead.")
        stages = tuple(s.strip() for s in args.stages.split(",")) if args.stages else None
        scene = load_scene(args.scene)
        hold = tuple(h.strip() for h in args.hold.split(",") if h.strip())
        text = calibrate_scene(
            scene, args.real, stages, args.trials, args.seed, args.evaluations, print, hold
        )
    except (SceneError, FidelityError) as err:
        print(f"ext-sense sim calibrate: {err}", file=sys.stderr)
        return 2
    if args.out:
        try:
            Path(args.out).parent.mkdir(parents=True, exist_ok=True)
            Path(args.out).write_text(text)
        except OSError as err:
            print(f"ext-sense sim calibrate: cannot write: {err}", file=sys.stderr)
            return 2
        print(f"wrote {args.out}")
    return 0


def _serve(args: argparse.Namespace) -> int:
    if args.device == "robotiq":
        from ext_sense_sim.devices.robotiq_emulator import serve

        return int(serve(args) or 0)
    from ext_sense_sim.errors import SceneError

    try:
        return _serve_sensor(args)
    except SceneError as err:
        print(f"ext-sense sim serve: {err}", file=sys.stderr)
        return 2


def _serve_sensor(args: argparse.Namespace) -> int:
    """``ext-sense sim serve nuskin|biotac``: stream a scene over a pty or a CAN channel."""
    from ext_sense_sim.errors import SceneError
    from ext_sense_sim.links import open_link
    from ext_sense_sim.scene import load_scene
    from ext_sense_sim.streaming import DEVICE_PRIORITY, stream

    default = {"nuskin": "tap_rod30_nuskin", "biotac": "tap_rod30_biotac"}[args.device]
    scene = load_scene(args.scene or default)
    if scene.sensor.label != args.device:
        raise SceneError(
            f"Scene '{scene.name}' is for sensor '{scene.sensor.label}', not '{args.device}'."
        )
    sink = open_link(
        "can" if args.can else "pty",
        link_path=args.link or "",
        can_channel=args.can or "",
        priority=DEVICE_PRIORITY,
    )
    where = f"CAN virtual channel {args.can}" if args.can else sink.path
    print(f"sim serve {args.device}: streaming scene {scene.name} on {where}", flush=True)
    try:
        stats = stream(
            scene,
            sink.write,
            seed=scene.seed if args.seed is None else args.seed,
            trials=args.trials,
            period_s=args.period,
            on_onset=lambda gt: print(
                f"trial {gt.trial} onset at {gt.onset_ns} ns {gt.class_label or gt.tap_position_m}",
                flush=True,
            ),
            ahead=True,
            priority=DEVICE_PRIORITY,
        )
    except KeyboardInterrupt:
        return 0
    finally:
        sink.close()
    print(f"sent {stats.trials} trials, {stats.bytes} bytes, late trials {stats.late_trials}")
    return 0
