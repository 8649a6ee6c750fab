"""The model card: a bundle's typed, versioned description, read only by :func:`read_card`.

A bundle directory holds ``model.onnx`` (features, scaler and estimator as one graph),
``model.joblib`` (the same fitted pipeline) and ``model_card.json``.
"""

from __future__ import annotations

import hashlib
import json
import math
from dataclasses import MISSING, dataclass, field, fields
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np

from ext_sense_perception.errors import PerceptionError
from ext_sense_perception.online.model_input import Geometry
from ext_sense_perception.profiles import TaskProfile
from ext_sense_runtime.enums import Sensor, Task

SCHEMA_VERSION = 2
"""Version 2: typed card with the task profile (version 1 cards had no profile: retrain)."""
ONNX_FILE = "model.onnx"
SKLEARN_FILE = "model.joblib"
CARD_FILE = "model_card.json"
LENGTH_TOLERANCE_M = 0.005
"""Held objects whose lengths differ by no more than this are the same length."""


class HeldObject(NamedTuple):
    """The object held between the fingers: its kind (``rod``, ``box``, ...) and length, m.

    ``length_m`` None: unknown, or the model was trained on several.
    """

    kind: str
    length_m: float | None = None

    def __str__(self) -> str:
        return self.kind if self.length_m is None else f"{self.length_m * 100:g} cm {self.kind}"

    @classmethod
    def parse(cls, text: str) -> HeldObject | None:
        """``"rod:0.30"`` (kind, length in m) or ``"rod"``; ``""``: None (no object named).

        PerceptionError: a kind that is no word, or a length that is no positive number.
        """
        text = text.strip()
        if not text:
            return None
        kind, _, length = text.partition(":")
        kind = kind.strip()
        if not kind.isidentifier():
            raise PerceptionError(
                f"A held object must be written kind or kind:length_m (e.g. 'rod:0.30'). Got "
                f"{text!r} instead."
            )
        if not length.strip():
            return cls(kind)
        try:
            value = float(length)
        except ValueError:
            value = math.nan
        if not (math.isfinite(value) and value > 0):
            raise PerceptionError(
                f"A held object's length must be a positive number of metres (e.g. 'rod:0.30'). "
                f"Got {text!r} instead."
            )
        return cls(kind, value)

    def to_text(self) -> str:
        """The form :meth:`parse` reads."""
        return self.kind if self.length_m is None else f"{self.kind}:{self.length_m:g}"


def object_mismatch(trained: HeldObject | None, held: HeldObject | None) -> str:
    """Why a model trained on ``trained`` must not serve a graph holding ``held`` ('' if not).

    An object or length either leaves open is no mismatch (see :func:`object_unknown`).
    """
    if trained is None or held is None:
        return ""
    lengths = (trained.length_m, held.length_m)
    other_length = None not in lengths and abs(lengths[0] - lengths[1]) > LENGTH_TOLERANCE_M
    if trained.kind != held.kind or other_length:
        return f"it was trained on a {trained}, and the graph holds a {held}"
    return ""


def object_unknown(trained: HeldObject | None, held: HeldObject | None) -> str:
    """A warning when a graph names its object and the card records none ('' otherwise)."""
    if trained is None and held is not None:
        return (
            f"the model card records no held object (a bundle made before cards recorded it): "
            f"accepted without checking it was trained on a {held}"
        )
    return ""


@dataclass(frozen=True)
class ModelCard:
    """What a bundle holds and how its windows must be cut.

    Attributes:
        profile: The task profile the training windows were cut with.
        window: The window the model accepts.
        feature_params: Parameters of the feature transformer (JSON values).
        model_params: Fixed estimator parameters.
        best_params: Hyper-parameters the grid search chose.
        rate_hz: Sampling rate the windows were reduced to, Hz.
        class_names: Classes (empty for regression).
        metrics: Cross-validated figures (``cv_mae_m``, ``residual_std_m`` or ``cv_accuracy``).
        excluded: Trials left out of the data.
        onnx: What the ONNX graph holds (None when export failed).
        anytime_post_ms: Post-onset times of the anytime bundles beside it, ms.
        anchor: What the training onsets were tied to (empty: the source's own).
        label_set: The classes decisions are restricted to (empty: all of ``class_names``).
        calibration: How ``ext-sense calibrate`` adapted the bundle to a session (empty: not).
        held_object: The object the windows were felt through (None: unknown, warned about).
        id: Task, sensor, features, model and a hash of the rest.
    """

    task: str
    sensor: str
    profile: TaskProfile
    window: Geometry
    features: str
    feature_params: dict[str, Any]
    model: str
    best_params: dict[str, Any]
    rate_hz: float
    class_names: tuple[str, ...]
    metrics: dict[str, float]
    n_train: int
    data: str
    data_hash: str
    model_params: dict[str, Any] = field(default_factory=dict)
    excluded: tuple[str, ...] = ()
    train_s: float = 0.0
    onnx: str | None = "whole pipeline (features + scaler + model) in ONNX"
    anytime_post_ms: tuple[float, ...] = ()
    anchor: str = ""
    sessions: tuple[str, ...] = ()
    label_set: tuple[str, ...] = ()
    calibration: dict[str, Any] = field(default_factory=dict)
    held_object: HeldObject | None = None
    id: str = ""
    schema_version: int = SCHEMA_VERSION

    def __post_init__(self) -> None:
        if self.schema_version != SCHEMA_VERSION:
            raise PerceptionError(
                f"The model card's 'schema_version' must be {SCHEMA_VERSION}. Got "
                f"{self.schema_version!r} instead: retrain the bundle with this version."
            )
        Task.parse(self.task, PerceptionError)
        Sensor.parse(self.sensor, PerceptionError)
        if self.profile.task.label != self.task:
            raise PerceptionError(
                f"The model card's profile is for {self.profile.task.label!r}, its task is "
                f"{self.task!r}."
            )
        _check_semantics(self)
        if not self.id:
            object.__setattr__(self, "id", self._make_id())

    @property
    def is_regression(self) -> bool:
        """Whether the model predicts a number (tap position) rather than a class."""
        return not self.class_names

    def _make_id(self) -> str:
        body = {k: v for k, v in self.to_dict().items() if k not in ("train_s", "id")}
        digest = hashlib.sha256(json.dumps(body, sort_keys=True, default=str).encode())
        return f"{self.task}-{self.sensor}-{self.features}-{self.model}-{digest.hexdigest()[:10]}"

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready values."""
        out = {f.name: getattr(self, f.name) for f in fields(self)}
        out["profile"] = self.profile.to_dict()
        out["window"] = self.window._asdict()
        for key in ("class_names", "excluded", "anytime_post_ms", "sessions", "label_set"):
            out[key] = list(out[key])
        out["held_object"] = None if self.held_object is None else self.held_object._asdict()
        if self.held_object is None:  # cards of unknown objects read as before the field
            del out["held_object"]
        return json.loads(json.dumps(out, default=_jsonable))

    @classmethod
    def from_dict(cls, values: dict[str, Any]) -> ModelCard:
        """A card from :meth:`to_dict` values (PerceptionError: bad or missing fields)."""
        if not isinstance(values, dict):
            raise PerceptionError(f"A model card must be a JSON object. Got {type(values)}.")
        names = {f.name for f in fields(cls)}
        required = {f.name for f in fields(cls) if f.default is f.default_factory is MISSING}
        missing, unknown = required - set(values), set(values) - names
        if missing or unknown:
            raise PerceptionError(
                f"The model card must have the fields {sorted(required)}; missing "
                f"{sorted(missing)}, unknown {sorted(unknown)}."
            )
        _check_types(values)
        v = dict(values)
        try:
            v["profile"] = TaskProfile.from_dict(v["profile"])
            v["window"] = Geometry(**v["window"])
            for key in ("class_names", "excluded", "sessions", "label_set"):
                v[key] = tuple(v.get(key, ()))
            v["anytime_post_ms"] = tuple(float(p) for p in v.get("anytime_post_ms", ()))
            held = v.get("held_object")
            v["held_object"] = None if held is None else HeldObject(**held)
            return cls(**v)
        except PerceptionError:
            raise
        except (TypeError, ValueError) as err:
            raise PerceptionError(f"The model card is invalid: {err}") from err

    def write(self, directory: Path) -> Path:
        """Write ``model_card.json`` into ``directory``; returns the file."""
        path = Path(directory) / CARD_FILE
        path.write_text(json.dumps(self.to_dict(), indent=2) + "\n")
        return path


_FIELD_KINDS: dict[str, tuple[type, ...]] = {
    "task": (str,),
    "sensor": (str,),
    "profile": (dict,),
    "window": (dict,),
    "features": (str,),
    "feature_params": (dict,),
    "model": (str,),
    "best_params": (dict,),
    "rate_hz": (int, float),
    "class_names": (list,),
    "metrics": (dict,),
    "n_train": (int,),
    "data": (str,),
    "data_hash": (str,),
    "model_params": (dict,),
    "excluded": (list,),
    "train_s": (int, float),
    "onnx": (str, type(None)),
    "anytime_post_ms": (list,),
    "anchor": (str,),
    "sessions": (list,),
    "label_set": (list,),
    "calibration": (dict,),
    "held_object": (dict, type(None)),
    "id": (str,),
    "schema_version": (int,),
}
"""The JSON kind of each card field: a string is never taken for a list of names."""

_WINDOW_FIELDS = ("n_channels", "n_samples", "period_ns", "pre_ns")


def _kind(value: object) -> str:
    return "a bool" if isinstance(value, bool) else type(value).__name__


def _check_types(values: dict[str, Any]) -> None:
    """The card's JSON values have the kinds of the schema (before any conversion)."""
    for name, kinds in _FIELD_KINDS.items():
        if name not in values:
            continue
        v = values[name]
        if isinstance(v, bool) or not isinstance(v, kinds):
            expected = " or ".join("null" if k is type(None) else k.__name__ for k in kinds)
            raise PerceptionError(
                f"The model card's {name!r} must be {expected}. Got {_kind(v)} {v!r} instead."
            )
    for name in ("class_names", "excluded", "sessions", "label_set"):
        for item in values.get(name, ()):
            if not isinstance(item, str) or not item:
                raise PerceptionError(
                    f"The model card's {name!r} must be a list of non-empty strings. Got "
                    f"{_kind(item)} {item!r} in it instead."
                )
    for item in values.get("anytime_post_ms", ()):
        if isinstance(item, bool) or not isinstance(item, (int, float)):
            raise PerceptionError(
                f"The model card's 'anytime_post_ms' must be a list of numbers. Got "
                f"{_kind(item)} {item!r} in it instead."
            )
    window = values["window"]
    if set(window) - {*_WINDOW_FIELDS, "sensor"}:
        raise PerceptionError(
            f"The model card's 'window' must have the fields {[*_WINDOW_FIELDS, 'sensor']}. "
            f"Got {sorted(window)} instead."
        )
    for name in _WINDOW_FIELDS:
        v = window.get(name)
        if isinstance(v, bool) or not isinstance(v, int):
            raise PerceptionError(
                f"The model card's 'window.{name}' must be an integer. Got {_kind(v)} {v!r} "
                "instead."
            )
    held = values.get("held_object")
    if held is not None:
        kind = held.get("kind")
        if set(held) - {"kind", "length_m"} or not (isinstance(kind, str) and kind):
            raise PerceptionError(
                "The model card's 'held_object' must be {'kind': str, 'length_m': number or "
                f"null}}. Got {held!r} instead."
            )
        length = held.get("length_m")
        number = isinstance(length, (int, float)) and not isinstance(length, bool)
        if length is not None and not (number and math.isfinite(length) and length > 0):
            raise PerceptionError(
                "The model card's 'held_object.length_m' must be a positive number of metres "
                f"or null. Got {length!r} instead."
            )
    for name, v in values["metrics"].items():
        if isinstance(v, bool) or not isinstance(v, (int, float)):
            raise PerceptionError(
                f"The model card's 'metrics.{name}' must be a number. Got {_kind(v)} {v!r} instead."
            )


def _fail(name: str, expected: str, got: object) -> PerceptionError:
    expected = expected[4:] if expected.startswith("to: ") else f"be {expected}"
    return PerceptionError(f"The model card's {name!r} must {expected}. Got {got!r} instead.")


def _check_semantics(card: ModelCard) -> None:
    """Rules that tie the fields together: the kind of model, the window, the periods."""
    task = Task.parse(card.task, PerceptionError)
    names = card.class_names
    if isinstance(names, str):
        raise _fail("class_names", "a list of class names, not one string", names)
    if task.is_regression and names:
        raise _fail("class_names", f"empty: {task.label} is a regression task", list(names))
    if not task.is_regression and (len(names) < 2 or len(set(names)) != len(names)):
        raise _fail(
            "class_names",
            f"at least 2 distinct names: {task.label} is a classification task",
            list(names),
        )
    w, profile = card.window, card.profile
    for name in ("n_channels", "n_samples", "period_ns"):
        if int(getattr(w, name)) <= 0:
            raise _fail(f"window.{name}", "positive", getattr(w, name))
    if w.sensor != card.sensor:
        raise _fail("window.sensor", f"the card's sensor {card.sensor!r}", w.sensor)
    # the window the model accepts must be cut from the windows the profile gives
    if w.pre_ns > profile.pre_ns:
        raise _fail("window.pre_ns", f"<= the profile's pre_ns ({profile.pre_ns})", w.pre_ns)
    if not 0 < w.post_ns <= profile.post_ns:
        raise _fail(
            "window",
            f"to: end within the profile's (0, {profile.post_ns}] ns after the onset",
            f"an end {w.post_ns} ns after it",
        )
    # online windows come at the profile's period: NUSkin bins add up to a coarser model bin,
    # BioTac samples cannot be resampled on the way
    period = profile.period_ns(card.sensor)
    if card.sensor == Sensor.NUSKIN.label:
        if w.period_ns % period:
            raise _fail("window.period_ns", f"a multiple of the profile's {period}", w.period_ns)
    elif w.period_ns != period:
        raise _fail("window.period_ns", f"the profile's {period}", w.period_ns)
    if (profile.pre_ns - w.pre_ns) % period:
        raise _fail("window.pre_ns", f"the profile's pre_ns less a multiple of {period}", w.pre_ns)
    if not (np.isfinite(card.rate_hz) and card.rate_hz > 0):
        raise _fail("rate_hz", "a positive number of Hz", card.rate_hz)
    if card.n_train < 0:
        raise _fail("n_train", ">= 0", card.n_train)
    post_ms = w.post_ns / 1e6
    for p in card.anytime_post_ms:
        if not (np.isfinite(p) and 0 < p < post_ms):
            raise _fail(
                "anytime_post_ms", f"each in (0, {post_ms:g}) ms", list(card.anytime_post_ms)
            )
    if set(card.label_set) - set(names):
        raise _fail("label_set", f"classes of class_names {list(names)}", list(card.label_set))


def _jsonable(v: Any) -> Any:
    if isinstance(v, np.integer):
        return int(v)
    if isinstance(v, np.floating):
        return float(v)
    if isinstance(v, (tuple, np.ndarray)):
        return list(v)
    if isinstance(v, Geometry):
        return v._asdict()
    if isinstance(v, TaskProfile):
        return v.to_dict()
    return str(v)


def jsonable(v: Any) -> Any:
    """A parameter value as JSON can hold it (NumPy scalars to Python, tuples to lists)."""
    return json.loads(json.dumps(v, default=_jsonable))


def read_card(directory: str | Path) -> ModelCard:
    """The card of a bundle, the one place cards are read (PerceptionError: bad or missing)."""
    path = Path(directory) / CARD_FILE
    if not path.is_file():
        raise PerceptionError(f"Model card missing: {str(path)!r} does not exist.")
    try:
        values = json.loads(path.read_text())
    except (OSError, UnicodeDecodeError, ValueError) as err:
        raise PerceptionError(f"Model card {str(path)!r} is not readable JSON: {err}") from err
    try:
        return ModelCard.from_dict(values)
    except PerceptionError as err:
        raise PerceptionError(f"Model card {str(path)!r} is corrupt: {err}") from err
