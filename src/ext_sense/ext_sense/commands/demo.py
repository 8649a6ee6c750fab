"""``ext-sense demo``: the main job, end to end, in one command.

1. Makes sure a tap-localisation model exists: when ``MODEL_DIR/model_card.json`` is missing (or
   was trained from other simulator or perception code) it trains one into
   ``tap_localization_<sensor>`` in the user's data directory (``$EXT_SENSE_MODELS`` when set;
   the place ``ext-sense models create`` writes and the graphs look in first, see
   ``ext_sense_perception.online.model_store``), or into ``--model DIR``. NUSkin: on windows
   cut from the emulated device's own byte stream by the driver's decoder and the window node's
   core (no train/serve skew); BioTac: ``ext-sense sim run`` then ``ext-sense train``.
2. Runs the ``tap_localization`` graph with ``source:=sim`` and ``hot_path:=one_process``
   (``--hot-path``): the emulated NUSkin streams over a pty, the driver publishes its bytes,
   ``contact_window`` cuts windows, ``contact_inference`` publishes
   ``/extsense/contact_estimate``, and ``estimate_monitor`` prints each estimate beside the
   simulator's ground truth and ends the graph after N taps with the line
   ``summary: taps=N mae_cm=X compute_p50_ms=Y compute_p99_ms=Z``.
"""

from __future__ import annotations

import argparse
import shutil
import sys
import time
from pathlib import Path
from typing import TextIO

TASK = "tap_localization"
TRAIN_SEED = 1000
"""Seed of the training taps (the demo's own taps use ``--seed``, default 1)."""
TRIAL_PERIOD_S = 1.0
"""Trial spacing of the training stream: ``sim_device``'s default ``trial_period_s``."""


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
        default=300,
        help="simulated taps to train on when the model is missing",
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
        help="the graph's hot_path: one_process (default; driver, window and inference nodes in "
        "one process, handing packets and windows over in process: the lowest latency measured "
        "on a 2-core machine, docs/runtime.md run 8) or processes (a process per node, the "
        "launch files' default)",
    )
    parser.add_argument("--scene", default="", help="simulator scene (default: the graph's)")
    parser.add_argument(
        "--port", default="", help="pty symlink the device and driver share (default: the graph's)"
    )
    parser.set_defaults(func=_demo)


def ensure_model(
    model_dir: Path,
    sensor: str,
    trials: int,
    retrain: bool = False,
    scene: str = "",
    log: TextIO = sys.stderr,
) -> int:
    """Train a model into ``model_dir`` unless a bundle is there.

    NUSkin: trained on the live path itself (no train/serve skew): the scene's trials are laid
    out as the emulated device streams them (``ext_sense_sim.trial_plan.lay_out_stream``: the
    receiver bytes, 1 s apart), decoded by the driver's decoder and arrival clock and cut by
    the ``contact_window`` node's core (``ext_sense_perception.data.device_stream``), each
    window labelled by its trial's ground truth. BioTac: the simulated dataset. Both train with
    the one training recipe (``ext_sense_perception.training.recipe.train_bundle``).

    Returns:
        0 on success, else the failing step's exit code.
    """
    from ext_sense.graphs import DEFAULT_SCENES

    scene = scene or DEFAULT_SCENES[(TASK, sensor)]
    fingerprint = training_fingerprint(sensor, scene, trials)
    stamp = model_dir / FINGERPRINT_FILE
    if (model_dir / "model_card.json").is_file() and not retrain:
        if stamp.is_file() and stamp.read_text().strip() == fingerprint:
            print(f"[demo] using model {model_dir}", file=log)
            return 0
        print(
            f"[demo] the model in {model_dir} was trained on another simulator, scene or "
            "windowing than this checkout has; retraining",
            file=log,
        )
        retrain = True
    if sensor == "nuskin":
        rc = train_on_stream(model_dir, scene, trials, log)
    else:
        rc = _train_on_dataset(model_dir, sensor, scene, trials, retrain, log)
    if rc == 0:
        stamp.write_text(fingerprint + "\n")
    return rc


FINGERPRINT_FILE = "demo_fingerprint.txt"


def training_fingerprint(sensor: str, scene: str, trials: int) -> str:
    """A hash of everything the demo's model is trained from.

    The sources of the simulator and of the perception package (effects, streaming, windows,
    features, models), the scene and the training settings. A cached model whose fingerprint
    differs was trained on data this checkout would no longer produce, and is retrained: a stale
    model silently kept after a simulator change scored 4.8 cm instead of 2.1 cm.
    """
    import hashlib

    import ext_sense_perception
    import ext_sense_sim

    digest = hashlib.sha256(f"{sensor}|{scene}|{trials}|{TRAIN_SEED}".encode())
    for package in (ext_sense_sim, ext_sense_perception):
        root = Path(package.__file__).parent
        for path in sorted(root.rglob("*")):
            if path.suffix in (".py", ".yaml") and "nodes" not in path.parts:
                digest.update(str(path.relative_to(root)).encode())
                digest.update(path.read_bytes())
    return digest.hexdigest()


def train_on_stream(model_dir: Path, scene_name: str, trials: int, log: TextIO) -> int:
    """Train the NUSkin model on windows cut from the device's own byte stream (see above)."""
    from ext_sense_perception.data.device_stream import window_set_from_stream
    from ext_sense_perception.errors import PerceptionError
    from ext_sense_perception.training.recipe import train_bundle
    from ext_sense_sim.errors import SceneError
    from ext_sense_sim.scene import load_scene
    from ext_sense_sim.trial_plan import lay_out_stream

    t0 = time.monotonic()
    print(f"[demo] streaming {trials} training taps ({scene_name}) offline", file=log)
    try:
        laid = lay_out_stream(load_scene(scene_name), TRAIN_SEED, trials, TRIAL_PERIOD_S)
        ws, counts = window_set_from_stream(laid.writes, laid.truths, source=f"stream:{scene_name}")
        print(
            f"[demo] {counts.labelled} labelled windows from {counts.words} words "
            f"({counts.unmatched_windows} unmatched windows, {counts.missed_trials} trials "
            f"without a window) in {time.monotonic() - t0:.1f} s",
            file=log,
        )
        t1 = time.monotonic()
        card = train_bundle(ws, str(model_dir))
    except (SceneError, PerceptionError) as err:
        print(f"ext-sense demo: error: {err}", file=sys.stderr)
        return 2
    print(
        f"[demo] trained {card.id} into {model_dir} in {time.monotonic() - t1:.1f} s; "
        f"metrics {card.metrics}",
        file=log,
    )
    return 0


def _train_on_dataset(
    model_dir: Path, sensor: str, scene_name: str, trials: int, retrain: bool, log: TextIO
) -> int:
    """Simulate a dataset (kept in ``datasets/`` beside the models directory) and train on it."""
    from ext_sense_perception.data.sources import from_sim_dataset
    from ext_sense_perception.errors import PerceptionError
    from ext_sense_perception.training.recipe import train_bundle
    from ext_sense_sim.errors import SceneError
    from ext_sense_sim.run import run_scene
    from ext_sense_sim.scene import load_scene

    data_dir = model_dir.parent.parent / "datasets" / f"{TASK}_{sensor}_train"
    try:
        if not (data_dir / "dataset.npz").is_file() or retrain:
            t0 = time.monotonic()
            print(
                f"[demo] simulating {trials} training taps ({scene_name}) into {data_dir}", file=log
            )
            if data_dir.exists():
                shutil.rmtree(data_dir)
            run_scene(load_scene(scene_name), data_dir, trials, TRAIN_SEED, formats=("npz",))
            print(f"[demo] simulated in {time.monotonic() - t0:.1f} s", file=log)
        t0 = time.monotonic()
        print(f"[demo] training {TASK}/{sensor} into {model_dir}", file=log)
        card = train_bundle(from_sim_dataset(data_dir / "dataset.npz"), model_dir)
    except (SceneError, PerceptionError) as err:
        print(f"ext-sense demo: error: {err}", file=sys.stderr)
        return 2
    print(f"[demo] trained {card.id} in {time.monotonic() - t0:.1f} s", file=log)
    return 0


def as_delivered(dataset: Path, out: Path) -> Path:
    """The dataset as the NUSkin driver delivers it live: every polarity 0.

    The receiver's words carry no polarity (real receivers leave the flag bit 0, and the
    emulated one does the same), so a model meant for the live graph and trained on a dataset
    must see events without it (the stream-trained demo model gets this by construction).
    """
    import numpy as np

    with np.load(dataset) as npz:
        arrays = {k: npz[k] for k in npz.files}
    arrays["ev_polarity"] = np.zeros_like(arrays["ev_polarity"])
    np.savez(out, **arrays)
    return out


def _demo(args: argparse.Namespace) -> int:
    from ext_sense.graphs import GRAPHS
    from ext_sense.runner import run_graph
    from ext_sense_perception.online.model_store import default_name, default_store

    model_dir = (args.model or default_store() / default_name(TASK, args.sensor)).resolve()
    rc = ensure_model(model_dir, args.sensor, args.train_trials, args.retrain, args.scene)
    if rc:
        print(f"ext-sense demo: preparing the model failed ({rc})", file=sys.stderr)
        return rc
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
    # python-can's virtual bus joins buses of one process only, so over CAN the whole graph
    # runs in one process.
    return run_graph(GRAPHS["tap_localization"], overrides, in_process=bool(args.can))
