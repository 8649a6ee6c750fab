"""Readers for the recordings models are trained on (no ROS); times become int64 ns.

Paper NUSkin ``.tact`` and ``*_essentials.csv``, paper BioTac ``.csv``, paper preprocessed
``.npz``, real NUSkin food-poking captures (``.tact`` plus a ROS 1 bag of ``FrankaState``), and
the simulator's ``dataset.npz`` (docs/conventions.md).
"""

from __future__ import annotations

import csv
from pathlib import Path
from typing import NamedTuple

import numpy as np
from rosbags.highlevel import AnyReader

from ext_sense_perception.data.validation import (
    BIOTAC_ADC,
    RULE_ADC,
    RULE_ORDER,
    RULE_TIME,
    InputPolicy,
    check_event_rows,
    check_trial_not_empty,
)
from ext_sense_perception.errors import PerceptionError
from ext_sense_runtime.records import EventBlock
from ext_sense_runtime.stamps import stamp_to_ns


class ArmMotion(NamedTuple):
    """When the arm moved in one recording, from its joint velocities."""

    start_ns: int
    stop_ns: int
    t_ns: np.ndarray  # state message times, int64
    speed: np.ndarray  # sum of |joint velocity|, rad/s


def _seconds_to_ns(text_seconds: np.ndarray) -> np.ndarray:
    """Float epoch seconds to int64 ns, rounded to the microsecond (float64 carries about that)."""
    return (np.round(np.asarray(text_seconds, dtype=np.float64) * 1e6).astype(np.int64)) * 1000


def _existing_file(path: str | Path, name: str = "path") -> Path:
    path = Path(path)
    if not path.is_file():
        raise PerceptionError(
            f"The {name!r} parameter must name an existing file. Got {str(path)!r} instead."
        )
    return path


def _load_rows(path: Path, n_cols: int) -> np.ndarray:
    path = _existing_file(path)
    try:
        rows = np.loadtxt(path, dtype=np.float64, ndmin=2)
    except ValueError as err:
        raise PerceptionError(f"Malformed event file {str(path)!r}: {err}") from err
    if rows.size == 0:
        return np.zeros((0, n_cols))
    if rows.shape[1] != n_cols:
        raise PerceptionError(
            f"Event file {str(path)!r} must have {n_cols} columns per line. Got {rows.shape[1]} "
            "instead."
        )
    return rows


def read_paper_tact(
    path: str | Path, policy: InputPolicy | None = None, markers: bool = True
) -> EventBlock:
    """The paper's NUSkin ``.tact`` (``isPos taxel removable t``), polarity +1 / -1, in time order.

    ``markers``: the first and last lines are markers (the paper's files), not events (the lab's
    rod-tap captures, REFERENCE.md section 2). PerceptionError: a missing or malformed file, or a
    row breaking a rule.
    """
    rows = _load_rows(Path(path), 4)
    rows = rows[1:-1] if markers else rows
    policy = policy or InputPolicy()
    after = "rows after the start marker" if markers else "rows from line 1"
    where = f"NUSkin events {str(path)!r} ({after})"
    rows = rows[check_event_rows(rows[:, 3], rows[:, 1], None, where, policy)]
    return EventBlock(
        t_ns=_seconds_to_ns(rows[:, 3]),
        taxel=rows[:, 1].astype(np.uint16),
        polarity=np.where(rows[:, 0] == 1, 1, -1).astype(np.int8),
        value=np.zeros(len(rows), np.uint16),
    )


def read_capture_tact(path: str | Path, policy: InputPolicy | None = None) -> EventBlock:
    """A real food-poking capture ``.tact``: ``col0 taxel value t`` between marker lines.

    The markers (``1 1 1 t`` first, ``2 2 2 t`` last) are dropped; ``col0`` (0 in these captures)
    becomes polarity 0, which counts +1 in windows. PerceptionError: as :func:`read_paper_tact`.
    """
    rows = _load_rows(Path(path), 4)
    first = 1
    if len(rows) and rows[0, 0] == 1 and rows[0, 1] == 1 and rows[0, 2] == 1:
        rows = rows[1:]
        first = 2
    if len(rows) and rows[-1, 0] == 2 and rows[-1, 1] == 2 and rows[-1, 2] == 2:
        rows = rows[:-1]
    policy = policy or InputPolicy()
    where = f"capture {str(path)!r} (rows from line {first})"
    rows = rows[check_event_rows(rows[:, 3], rows[:, 1], rows[:, 2], where, policy)]
    return EventBlock(
        t_ns=_seconds_to_ns(rows[:, 3]),
        taxel=rows[:, 1].astype(np.uint16),
        polarity=np.where(rows[:, 0] == 1, 1, 0).astype(np.int8),
        value=rows[:, 2].astype(np.uint16),
    )


def read_csv_columns(path: str | Path) -> dict[str, np.ndarray]:
    """A CSV with a header as columns, numbers where all parse (PerceptionError: none/empty)."""
    path = _existing_file(path)
    with path.open(newline="") as fh:
        reader = csv.reader(fh)
        try:
            header = next(reader)
        except StopIteration as err:
            raise PerceptionError(f"CSV file {str(path)!r} is empty.") from err
        cols: list[list[str]] = [[] for _ in header]
        for row in reader:
            for i, v in enumerate(row[: len(header)]):
                cols[i].append(v)
    out: dict[str, np.ndarray] = {}
    for name, values in zip(header, cols, strict=True):
        try:
            out[name.strip()] = np.asarray(values, dtype=np.float64)
        except ValueError:
            out[name.strip()] = np.asarray(values)
    return out


def read_biotac_csv(path: str | Path) -> tuple[np.ndarray, np.ndarray]:
    """The paper's BioTac CSV (columns ``pac``, ``t``) as ``(pac (n,) float64, t_ns (n,) int64)``.

    A missing column or any bad row is a PerceptionError: dropping a sample would shift every later
    one.
    """
    cols = read_csv_columns(path)
    for name in ("pac", "t"):
        if name not in cols:
            raise PerceptionError(
                f"BioTac CSV {str(path)!r} must have a {name!r} column. Got {sorted(cols)} instead."
            )
    where = f"BioTac CSV {str(path)!r} (rows after the header)"
    try:
        pac = cols["pac"].astype(np.float64)
        t = cols["t"].astype(np.float64)
    except ValueError as err:
        raise PerceptionError(f"{where}: 'pac' and 't' must be numbers: {err}") from err
    strict = InputPolicy()
    with np.errstate(invalid="ignore"):
        strict.keep(~((pac >= BIOTAC_ADC[0]) & (pac <= BIOTAC_ADC[1])), RULE_ADC, where, pac)
        strict.keep(~(np.isfinite(t) & (t >= 0)), RULE_TIME, where, t)
    strict.keep(np.r_[False, np.diff(t) < 0], RULE_ORDER, where, t)
    return pac, _seconds_to_ns(t)


def load_preprocessed_npz(path: str | Path) -> tuple[np.ndarray, np.ndarray]:
    """The paper's preprocessed ``.npz``: ``(signals (n, n_channels, n_samples) float32, labels)``.

    PerceptionError: a missing file, or one without the arrays.
    """
    path = Path(path)
    try:
        with np.load(path, allow_pickle=False) as z:
            signals, labels = z["signals"], z["labels"]
    except (OSError, KeyError, ValueError) as err:
        raise PerceptionError(f"Cannot read preprocessed npz {str(path)!r}: {err}") from err
    signals = np.asarray(signals, dtype=np.float32)
    if signals.ndim == 2:
        signals = signals[:, None, :]
    return signals, labels


def read_arm_motion(bag: str | Path, speed_threshold: float = 0.05) -> ArmMotion:
    """Start and stop of the arm's motion from a ROS 1 bag of ``franka_msgs/msg/FrankaState``.

    Motion is where the sum of absolute joint velocities exceeds ``speed_threshold`` rad/s.
    PerceptionError: a missing or unreadable bag, or an arm that never moves.
    """
    bag = _existing_file(bag, "bag")
    try:
        times: list[int] = []
        speeds: list[float] = []
        with AnyReader([bag]) as reader:
            conns = [c for c in reader.connections if c.msgtype.endswith("FrankaState")]
            for conn, _, raw in reader.messages(connections=conns):
                msg = reader.deserialize(raw, conn.msgtype)
                times.append(stamp_to_ns(msg.header.stamp))
                speeds.append(float(np.abs(np.asarray(msg.dq)).sum()))
    except Exception as err:  # rosbags raises many types on corrupt bags
        raise PerceptionError(f"Cannot read arm state from bag {str(bag)!r}: {err}") from err
    t = np.asarray(times, dtype=np.int64)
    s = np.asarray(speeds)
    moving = np.flatnonzero(s > speed_threshold)
    if len(moving) == 0:
        raise PerceptionError(
            f"The arm never moves in {str(bag)!r} (speed threshold {speed_threshold} rad/s)."
        )
    return ArmMotion(int(t[moving[0]]), int(t[moving[-1]]), t, s)


class Recording(NamedTuple):
    """One labelled trial of the real captures (``motion`` None when it has no arm bag)."""

    name: str
    label: str
    events: EventBlock
    motion: ArmMotion | None
    capture_start_ns: int


def capture_start_ns(path: str | Path, events: EventBlock) -> int:
    """A capture's ``1 1 1 t`` marker time, else its first event's, ns (else PerceptionError)."""
    with open(path, encoding="ascii", errors="replace") as fh:
        first = fh.readline().split()
    if len(first) == 4 and first[:3] == ["1", "1", "1"]:
        try:
            t = float(first[3])
        except ValueError:
            t = float("nan")
        if np.isfinite(t):
            return int(_seconds_to_ns(np.array([t]))[0])
    if not events.size:
        raise PerceptionError(f"Capture {str(path)!r} has no start marker and no event.")
    return int(events.t_ns[0])


def food_poking_trials(
    directory: str | Path,
    include_empty: bool = False,
    policy: InputPolicy | None = None,
    arm_motion: bool = True,
) -> tuple[list[Recording], list[str]]:
    """All trials of a session of real food-poking captures, and the names of those excluded.

    The single ``empty`` trial is excluded unless ``include_empty`` (one trial cannot be split);
    a lenient ``policy`` excludes a trial with no valid event. ``arm_motion`` reads each trial's
    arm bag. PerceptionError: no trials, or a trial's bag missing.
    """
    directory = Path(directory)
    if not directory.is_dir():
        raise PerceptionError(
            f"The 'data' parameter must be a directory. Got {str(directory)!r} instead."
        )
    policy = policy or InputPolicy()
    recs: list[Recording] = []
    excluded: list[str] = []
    for tact in sorted(directory.glob("*_zero_*.tact")):
        if tact.name.endswith("_raw.tact"):
            continue
        name = tact.stem
        label = name.split("_zero_")[0]
        if label == "empty" and not include_empty:
            excluded.append(name)
            continue
        events = read_capture_tact(tact, policy)
        if not check_trial_not_empty(events.size, f"capture {str(tact)!r}", policy):
            excluded.append(name)
            continue
        motion = read_arm_motion(tact.with_suffix(".bag")) if arm_motion else None
        recs.append(Recording(name, label, events, motion, capture_start_ns(tact, events)))
    if not recs:
        raise PerceptionError(_no_trials(directory, excluded))
    return recs, excluded


def _no_trials(directory: Path, excluded: list[str]) -> str:
    """Why a folder given as food-poking captures gave no trial, and what to give instead."""
    where = str(directory)
    if excluded:
        return (
            f"No trial of the capture folder {where!r} is left: every capture was excluded "
            f"({', '.join(excluded)})."
        )
    if (directory / "run.json").is_file():
        sessions = [str(directory / p) for p in ("dataset.npz", "bag") if (directory / p).exists()]
        use = (
            "give one of its sessions instead: " + " or ".join(f"--data {p}" for p in sessions)
            if sessions
            else "rerun it with --formats npz or bag and give its dataset.npz or bag"
        )
        return (
            f"{where!r} is the output folder of 'ext-sense sim run', not a food-poking capture "
            f"folder; {use}."
        )
    return (
        f"{where!r} is not a food-poking capture folder: it holds no '<food>_zero_<n>.tact' "
        "capture. A folder given as data must hold those captures, or be a rosbag2 bag "
        "(metadata.yaml, .mcap or .db3)."
    )


def load_sim_dataset(path: str | Path) -> dict[str, np.ndarray]:
    """The simulator's ``dataset.npz`` as arrays, strings as ``str`` (PerceptionError: bad)."""
    path = Path(path)
    try:
        with np.load(path, allow_pickle=False) as z:
            data = {k: z[k] for k in z.files}
    except (OSError, ValueError) as err:
        raise PerceptionError(f"Cannot read dataset {str(path)!r}: {err}") from err
    for key in ("task", "sensor", "y", "onset_ns"):
        if key not in data:
            raise PerceptionError(
                f"Dataset {str(path)!r} must hold {key!r}. Got {sorted(data)} instead."
            )
    for key in ("task", "sensor", "label_kind"):
        if key in data:
            data[key] = str(data[key])
    return data
