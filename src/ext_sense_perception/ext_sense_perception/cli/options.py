"""The options that name sessions, and loading them (shared by every perception command).

Handlers import the heavy modules lazily, so ``ext-sense --help`` stays fast.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path
from typing import TYPE_CHECKING, NamedTuple

from ext_sense_perception.errors import PerceptionError
from ext_sense_runtime.stamps import MS

if TYPE_CHECKING:
    from ext_sense_perception.data.sessions import Session
    from ext_sense_perception.data.window_set import WindowSet


def add_data_options(p: argparse.ArgumentParser) -> None:
    """Options naming the sessions and how their windows are cut (see :func:`load_sessions`)."""
    p.add_argument(
        "--task",
        help="tap_localization, handover_stability or food_identification (a bag, a "
        "simulator dataset or a bundle names its own)",
    )
    p.add_argument("--sensor", help="nuskin or biotac")
    p.add_argument(
        "--data",
        action="append",
        required=True,
        help="a session: simulator dataset.npz, the paper's preprocessed .npz, a food-poking "
        "capture directory, a rosbag2 bag (directory, .mcap or .db3), or (features only) one "
        "recording (.tact / BioTac .csv); repeat for several sessions (pooled)",
    )
    p.add_argument(
        "--anchor",
        choices=("arm_motion", "capture_start", "contact"),
        default=None,
        help="capture folders: what food windows are tied to: the arm's motion start (needs the "
        "arm bags), the capture's start, or the fork's tactile onset detected as live (default: "
        "arm_motion where every trial has its bag, else capture_start)",
    )
    bag = p.add_argument_group("bags (--data a rosbag2 bag)")
    bag.add_argument(
        "--onsets",
        choices=("auto", "truth", "detected"),
        default="auto",
        help="window onsets: the ground-truth stamps, or detected from the signal as live and "
        "labelled by the nearest ground truth (default: truth when the bag has any)",
    )
    bag.add_argument(
        "--events-topic", default="/extsense/nuskin/events", help="TaxelEventBatch topic"
    )
    bag.add_argument("--frames-topic", default="/extsense/biotac/frames", help="BioTacFrame topic")
    bag.add_argument(
        "--truth-topic", default="/extsense/ground_truth", help="ContactGroundTruth topic"
    )
    p.add_argument(
        "--post-ms", type=float, default=None, help="post-contact window used, ms (default: all)"
    )
    p.add_argument(
        "--rate-hz",
        type=float,
        default=None,
        help="reduced sampling rate, Hz (NUSkin refractory / BioTac decimation)",
    )
    p.add_argument(
        "--lenient",
        action="store_true",
        help="drop and count input rows and trials that break a rule (non-finite or out-of-range "
        "times, taxels outside 1..80, values outside their field, time going backwards, empty "
        "trials) instead of stopping at the first one; the counts are printed",
    )


class Wanted(NamedTuple):
    """The windows a model bundle takes (``who`` names it in errors; ``anchor`` empty: none)."""

    task: str
    sensor: str
    anchor: str
    who: str


def _load_one(
    path: Path, args: argparse.Namespace, need_labels: bool, wanted: Wanted | None
) -> WindowSet:
    """One ``--data`` path as a window set (bags, recordings, datasets, capture folders).

    Sources that say their own task and sensor (capture folders, simulator datasets) and bags
    are read as they are and then checked against ``--task``/``--sensor`` and ``wanted``;
    the others are read as the task and sensor given (else the bundle's).
    """
    from ext_sense_perception.data.bags import BagTopics, is_bag, window_set_from_bag
    from ext_sense_perception.data.recordings import from_recording
    from ext_sense_perception.data.sources import load_window_set, names_own_kind
    from ext_sense_perception.data.validation import InputPolicy

    policy = InputPolicy(lenient=args.lenient)
    task = args.task or (wanted.task if wanted else None)
    sensor = args.sensor or (wanted.sensor if wanted else None)
    # NUSkin refractory drop on events; BioTac decimates in the features
    nuskin_rate = args.rate_hz if sensor != "biotac" else None
    if is_bag(path):
        topics = BagTopics(args.events_topic, args.frames_topic, args.truth_topic)
        ws, counts = window_set_from_bag(
            path,
            args.task,  # else the bag's own, checked below
            sensor,
            topics=topics,
            onsets=args.onsets,
            rate_hz=args.rate_hz,
            require_labels=need_labels,
        )
        print(
            f"{path}: " + ", ".join(f"{k} {v}" for k, v in counts._asdict().items()),
            file=sys.stderr,
        )
    elif path.suffix in (".tact", ".csv"):
        if not (task and sensor):
            raise PerceptionError(
                f"The '--task' and '--sensor' options are needed for a recording ({path.name}). "
                "Got none."
            )
        essentials = getattr(args, "essentials", None)  # a features option
        ws = from_recording(path, task, sensor, essentials, policy=policy)
    elif names_own_kind(path):
        anchor = args.anchor
        if anchor is None and wanted and wanted.anchor and path.is_dir():
            anchor = wanted.anchor  # a bundle of capture windows: cut them alike
        ws = load_window_set(path, rate_hz=nuskin_rate, policy=policy, anchor=anchor)
    else:
        ws = load_window_set(
            path, task, sensor, rate_hz=nuskin_rate, policy=policy, anchor=args.anchor
        )
    _check_kind(path, ws, args, wanted)
    if args.lenient:
        print(f"{path}: {policy.summary()}", file=sys.stderr)
    return ws


def _check_kind(path: Path, ws: WindowSet, args: argparse.Namespace, wanted: Wanted | None) -> None:
    """Raise a PerceptionError (naming who asks) unless ``ws`` is of the kind asked for."""
    from ext_sense_runtime.enums import Sensor, Task

    asks = []
    for what, given, kind in (("task", args.task, Task), ("sensor", args.sensor, Sensor)):
        if given and kind.parse(given, PerceptionError).label != getattr(ws, what):
            asks.append(f"the '--{what}' option asks for {kind.parse(given).label}")
    if wanted and (wanted.task, wanted.sensor) != (ws.task, ws.sensor):
        asks.append(
            f"{wanted.who} is a {wanted.task}/{wanted.sensor} model: give it "
            f"{wanted.task}/{wanted.sensor} sessions, or a {ws.task}/{ws.sensor} bundle"
        )
    if asks:
        raise PerceptionError(
            f"The data {str(path)!r} holds {ws.task}/{ws.sensor} windows, but "
            + "; ".join(asks)
            + "."
        )


def load_sessions(
    args: argparse.Namespace, *, need_labels: bool = True, wanted: Wanted | None = None
) -> list[Session]:
    """Every ``--data`` as a session: its windows (cropped by ``--post-ms``) and metadata.

    ``need_labels``: bags must hold ground truth; ``wanted``: the windows a bundle takes (``score``,
    ``calibrate``). PerceptionError: unreadable data, ``session.json`` breaking its schema or naming
    another sensor, or data of another task or sensor than asked for.
    """
    from ext_sense_perception.data.sessions import as_session

    sessions = []
    for data in args.data:
        path = Path(data)
        ws = _load_one(path, args, need_labels, wanted)
        if args.post_ms is not None:
            if not math.isfinite(args.post_ms):
                raise PerceptionError(
                    f"The '--post-ms' option must be a finite number of ms. Got {args.post_ms} "
                    "instead."
                )
            ws = ws.crop(round(args.post_ms * MS))
        sessions.append(as_session(path, ws))
    return sessions


def write_json(path: str | None, record: dict) -> None:
    """Write ``record`` as indented JSON to ``path`` (``--json``; None: nowhere)."""
    if path:
        Path(path).parent.mkdir(parents=True, exist_ok=True)
        Path(path).write_text(json.dumps(record, indent=2) + "\n")


def fail(err: Exception) -> int:
    """Print a perception error as one line; exit status 2."""
    print(f"ext-sense: error: {err}", file=sys.stderr)
    return 2


def load_pooled(args: argparse.Namespace, *, need_labels: bool = True) -> WindowSet:
    """The ``--data`` sessions pooled into one window set."""
    from ext_sense_perception.data.sessions import pooled

    return pooled(load_sessions(args, need_labels=need_labels))


def add_cluster_options(p: argparse.ArgumentParser, *, default_cache: str) -> None:
    """``--workers`` / ``--scheduler`` / ``--cache``: where the protocol's fits run and are kept."""
    g = p.add_argument_group("distributed fits (Dask)")
    g.add_argument(
        "--workers",
        type=int,
        default=None,
        help="start a local Dask cluster of N single-threaded worker processes for the fits "
        "(stopped at the end)",
    )
    g.add_argument(
        "--scheduler",
        default=None,
        help="run the fits on an existing Dask cluster (tcp://HOST:PORT); its workers need this "
        "project's environment",
    )
    g.add_argument(
        "--cache",
        default=None,
        help=f"keep every finished fit here; a rerun computes only what changed or failed "
        f"(default: {default_cache}; 'none' for no cache)",
    )


def cache_dir(text: str | None, default: Path | None) -> Path | None:
    """The ``--cache`` directory (``none``: no cache)."""
    if text is None:
        return default
    return None if text.strip().lower() == "none" else Path(text)
