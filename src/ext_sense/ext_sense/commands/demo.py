"""``ext-sense demo``: the main job, end to end, in one command.

1. Trains the tap-localisation model when it is missing or stale (``tap_localization_<sensor>``
   in the user's model store, or ``--model DIR``), as ``ext-sense models create`` does; the
   NUSkin model on windows cut from the emulated device's own byte stream.
2. Runs the ``tap_localization`` graph on the simulator: the monitor prints each estimate
   beside the ground truth and ends after N taps with
   ``summary: taps=N mae_cm=X compute_p50_ms=Y compute_p99_ms=Z``.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

TASK = "tap_localization"


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``demo`` subcommand."""
    parser = subparsers.add_parser(
        "demo",
        help="the main job: tap localization on the emulated NUSkin, end to end",
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("--taps", type=int, default=30, help="taps before the summary")
    parser.add_argument("--sensor", choices=("nuskin", "biotac"), default="nuskin")
    parser.add_argument(
        "--model",
        type=Path,
        help="model bundle directory, trained when missing (default: tap_localization_<sensor> "
        "in $EXT_SENSE_MODELS when set, else in ~/.local/share/ext_sense/models)",
    )
    parser.add_argument("--backend", choices=("onnx", "sklearn"), default="onnx")
    parser.add_argument(
        "--train-trials",
        type=int,
        default=None,
        help="simulated taps to train on when the model is missing (default: as 'ext-sense "
        "models create', so both keep the same model)",
    )
    parser.add_argument("--retrain", action="store_true", help="train even if the model exists")
    parser.add_argument("--seed", type=int, default=1, help="seed of the demo's taps")
    parser.add_argument(
        "--can",
        default="",
        metavar="CHANNEL",
        help="stream over this python-can virtual channel instead of a pty",
    )
    parser.add_argument(
        "--hot-path",
        choices=("one_process", "processes"),
        default="one_process",
        help="the graph's hot_path: one_process (default, as the launch files'; driver, window "
        "and inference nodes in one process, handing packets and windows over in process) or "
        "processes (a process per node)",
    )
    parser.add_argument("--scene", default="", help="simulator scene (default: the graph's)")
    parser.add_argument(
        "--port", default="", help="pty symlink the device and driver share (default: the graph's)"
    )
    parser.set_defaults(func=_demo)


def _log(line: str) -> None:
    print(f"[demo] {line}", file=sys.stderr)


def _demo(args: argparse.Namespace) -> int:
    from ext_sense.graphs import GRAPHS
    from ext_sense.runner import run_graph
    from ext_sense_perception.errors import PerceptionError
    from ext_sense_perception.online.model_store import default_name, default_store
    from ext_sense_sim.default_models import ensure_model
    from ext_sense_sim.errors import SceneError

    model_dir = (args.model or default_store() / default_name(TASK, args.sensor)).resolve()
    try:
        ensure_model(
            model_dir, TASK, args.sensor, args.train_trials, args.scene, args.retrain, _log
        )
    except (SceneError, PerceptionError) as err:
        print(f"ext-sense demo: error: {err}", file=sys.stderr)
        return 2
    overrides = {
        "sensor": args.sensor,
        "source": "sim",
        "trials": str(args.taps),
        "seed": str(args.seed),
        "model": str(model_dir),
        "backend": args.backend,
        "monitor": "true",
        "hot_path": args.hot_path,
    }
    if args.can:
        overrides["can_channel"] = args.can
    if args.scene:
        overrides["scene"] = args.scene
    if args.port:
        overrides["port"] = args.port
    print(
        f"[demo] running the tap_localization graph for {args.taps} taps "
        f"(hot_path:={args.hot_path})",
        file=sys.stderr,
    )
    # python-can's virtual bus joins buses of one process only
    return run_graph(GRAPHS["tap_localization"], overrides, in_process=bool(args.can))
