"""Sessions, the unit of data: a recording with its metadata beside it (no ROS).

A session is one capture folder, bag or simulator run. Its metadata lives in ``session.json`` inside
the folder or as ``<file>.session.json``; without one (the read-only captures) it is inferred from
the data. The label set is what the session can hold; scoring restricts decisions to it.
"""

from __future__ import annotations

import datetime as dt
import json
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np

from ext_sense_perception.data.bags import is_bag
from ext_sense_perception.data.sources import load_window_set
from ext_sense_perception.data.validation import InputPolicy
from ext_sense_perception.data.window_set import WindowSet, common_held_object
from ext_sense_perception.errors import PerceptionError
from ext_sense_perception.profiles import Anchor
from ext_sense_runtime.enums import Sensor

SESSION_FILE = "session.json"


@dataclass(frozen=True)
class SessionInfo:
    """A session's metadata (empty strings: unknown).

    ``date`` is ``YYYY-MM-DD``; ``labels`` the classes the session may hold (empty: the data's own);
    ``baseline`` a capture with nothing touched, relative to the session; ``inferred``: not read
    from a file.
    """

    name: str
    date: str = ""
    sensor: str = ""
    sensor_id: str = ""
    robot: str = ""
    labels: tuple[str, ...] = ()
    notes: str = ""
    baseline: str = ""
    inferred: bool = field(default=False, compare=False)

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready values (``session.json``, reports)."""
        out = asdict(self)
        out["labels"] = list(self.labels)
        out.pop("inferred")
        return out


class Session(NamedTuple):
    """A session's metadata and its windows."""

    info: SessionInfo
    path: str
    windows: WindowSet


def metadata_file(path: str | Path) -> Path:
    """Where a session's ``session.json`` lives for data at ``path``."""
    p = Path(path)
    return p / SESSION_FILE if p.is_dir() else p.with_name(p.name + "." + SESSION_FILE)


def read_info(path: str | Path) -> SessionInfo | None:
    """The checked ``session.json`` at ``path`` (None: none; PerceptionError: bad)."""
    meta = metadata_file(path)
    if not meta.is_file():
        return None
    try:
        values = json.loads(meta.read_text())
    except (OSError, UnicodeDecodeError, json.JSONDecodeError, RecursionError) as err:
        raise PerceptionError(f"Cannot read session metadata {str(meta)!r}: {err}") from err
    return info_from_json(values, meta, _default_name(path))


SESSION_SCHEMA: dict[str, str] = {
    "name": "a non-empty string",
    "date": "a day as a 'YYYY-MM-DD' string, or ''",
    "sensor": "one of 'nuskin', 'biotac', or ''",
    "sensor_id": "a string",
    "robot": "a string",
    "labels": 'a list of distinct non-empty strings, e.g. ["tofu", "apple"]',
    "notes": "a string",
    "baseline": "a string (a capture's path relative to the session)",
}
"""The fields of ``session.json`` and what each must hold: the one schema every loader uses."""


def info_from_json(values: object, meta: str | Path, default_name: str) -> SessionInfo:
    """The metadata of a ``session.json``'s parsed ``values`` (PerceptionError: a field is bad)."""
    if not isinstance(values, dict) or not set(values) <= set(SESSION_SCHEMA):
        got = (
            f"the unknown fields {sorted(set(values) - set(SESSION_SCHEMA))}"
            if isinstance(values, dict)
            else _shown(values)
        )
        raise PerceptionError(
            f"Session metadata {str(meta)!r} must be an object with fields among "
            f"{list(SESSION_SCHEMA)}. Got {got} instead."
        )
    for name, value in values.items():
        if not _fits(name, value):
            raise PerceptionError(
                f"Session metadata {str(meta)!r}: the field {name!r} must be "
                f"{SESSION_SCHEMA[name]}. Got {_shown(value)} instead."
            )
    fields = dict(values)
    fields.setdefault("name", default_name)
    fields["labels"] = tuple(fields.get("labels", ()))
    return SessionInfo(**fields)


def _shown(value: object) -> str:
    """A JSON value as error messages show it: its kind and its JSON text."""
    if value is None:
        return "null"
    kinds = {bool: "bool", int: "number", float: "number", str: "string", list: "list"}
    return f"{kinds.get(type(value), 'object')} {json.dumps(value)}"


def _fits(name: str, value: object) -> bool:
    """Whether ``value`` is what :data:`SESSION_SCHEMA` asks of the field ``name``."""
    if name == "labels":
        return (
            isinstance(value, list)
            and all(isinstance(v, str) and v.strip() for v in value)
            and len(set(value)) == len(value)
        )
    if not isinstance(value, str):
        return False
    if name == "name":
        return bool(value.strip())
    if name == "sensor":
        return value in ("", *(s.label for s in Sensor))
    if name == "date" and value:
        try:
            return dt.date.fromisoformat(value).isoformat() == value
        except ValueError:
            return False
    return True


def write_info(path: str | Path, info: SessionInfo) -> Path:
    """Write ``info`` as the metadata of the session at ``path``; returns the file."""
    meta = metadata_file(path)
    meta.write_text(json.dumps(info.to_dict(), indent=2) + "\n")
    return meta


def _default_name(path: str | Path) -> str:
    p = Path(path)
    return p.name if p.is_dir() else p.stem


def infer_info(path: str | Path, ws: WindowSet) -> SessionInfo:
    """Metadata inferred from the data itself (no ``session.json``)."""
    p = Path(path)
    date = ""
    baseline = ""
    if p.is_dir() and not is_bag(p):
        first = sorted(p.glob("*_zero_*.tact"))
        if first:
            date = _capture_date(first[0])
        if (p / "zero.tact").is_file():
            baseline = "zero.tact"
    return SessionInfo(
        name=_default_name(p),
        date=date,
        sensor=ws.sensor,
        labels=tuple(ws.class_names),
        baseline=baseline,
        inferred=True,
    )


def _capture_date(tact: Path) -> str:
    """The UTC day of a capture's first line (host epoch seconds), ``""`` if unreadable."""
    try:
        with open(tact, encoding="ascii", errors="replace") as fh:
            t = float(fh.readline().split()[3])
        return dt.datetime.fromtimestamp(t, tz=dt.timezone.utc).date().isoformat()
    except (OSError, IndexError, ValueError, OverflowError):
        return ""


def load_session(
    path: str | Path,
    task: str | None = None,
    sensor: str | None = None,
    rate_hz: float | None = None,
    policy: InputPolicy | None = None,
    anchor: Anchor | str | None = None,
) -> Session:
    """One session's windows and metadata (arguments as :func:`~.sources.load_window_set`'s).

    PerceptionError: unreadable data or metadata, or metadata naming another sensor.
    """
    ws = load_window_set(path, task, sensor, rate_hz=rate_hz, policy=policy, anchor=anchor)
    return as_session(path, ws)


def as_session(path: str | Path, ws: WindowSet) -> Session:
    """The session of the windows ``ws`` loaded from ``path``, each window named by the session.

    PerceptionError: metadata that breaks the schema, or names another sensor than the data's.
    """
    info = read_info(path) or infer_info(path, ws)
    if info.sensor and info.sensor != ws.sensor:
        raise PerceptionError(
            f"Session metadata {str(metadata_file(path))!r}: the field 'sensor' must be the "
            f"data's {ws.sensor!r}. Got {info.sensor!r} instead."
        )
    ws = ws._replace(sessions=np.full(len(ws.y), info.name))
    return Session(info, str(path), ws)


def pooled(sessions: list[Session]) -> WindowSet:
    """The windows of several sessions as one set (trial groups kept apart per session).

    PerceptionError: no sessions, two of one name, or differing task, sensor, geometry, anchor.
    """
    if not sessions:
        raise PerceptionError("The 'sessions' parameter must name at least one session.")
    names = [s.info.name for s in sessions]
    if len(set(names)) != len(names):
        raise PerceptionError(f"Session names must differ. Got {names} instead.")
    sets = [s.windows for s in sessions]
    first = sets[0]
    for s, ws in zip(sessions[1:], sets[1:], strict=True):
        for what in ("task", "sensor", "anchor", "geometry"):
            if getattr(ws, what) != getattr(first, what):
                raise PerceptionError(
                    f"Session {s.info.name!r} has {what} {getattr(ws, what)!r}; "
                    f"{names[0]!r} has {getattr(first, what)!r}. Pool sessions cut alike"
                    + (" (give --anchor)." if what == "anchor" else ".")
                )
    if len(sets) == 1:
        return first
    y_all = np.concatenate([ws.y for ws in sets])
    names_all = () if first.is_regression else tuple(sorted(set(y_all.tolist()) - {""}))
    offset, groups = 0, []
    for ws in sets:
        g = np.unique(ws.groups, return_inverse=True)[1]
        groups.append(g + offset)
        offset += int(g.max()) + 1 if len(g) else 0
    return first._replace(
        X=np.concatenate([ws.X for ws in sets]),
        y=y_all,
        class_names=names_all,
        groups=np.concatenate(groups),
        rod_length_m=np.concatenate([ws.rod_length_m for ws in sets]),
        source=" + ".join(ws.source for ws in sets),
        data_hash="+".join(ws.data_hash for ws in sets),
        excluded=tuple(f"{n}/{e}" for n, ws in zip(names, sets, strict=True) for e in ws.excluded),
        sessions=np.concatenate([ws.session_of for ws in sets]),
        held_object=common_held_object(sets),
    )
