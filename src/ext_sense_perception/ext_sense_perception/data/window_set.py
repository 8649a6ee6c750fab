# ruff: noqa: N806  (X for the window matrix, as in scikit-learn)
"""Labelled sets of contact windows: the record every data source becomes (no ROS)."""

from __future__ import annotations

import hashlib
from pathlib import Path
from typing import NamedTuple

import numpy as np

from ext_sense_perception.errors import PerceptionError
from ext_sense_perception.online.model_card import LENGTH_TOLERANCE_M, HeldObject
from ext_sense_perception.online.model_input import Geometry
from ext_sense_perception.online.window import ContactWindow, WindowConfig
from ext_sense_perception.profiles import TaskProfile, profile_for


class WindowSet(NamedTuple):
    """Windows with labels.

    ``X`` is ``(n_windows, n_channels, n_samples)`` float32; ``y`` float64 metres (regression) or
    ``<U`` class labels; ``groups`` the trial of each window. ``profile`` is the task profile the
    windows were cut with (None: the task's own), recorded in a model's card so the live graph cuts
    the same windows. ``sessions`` names each window's session (None: one unnamed session);
    ``anchor`` what the onsets were tied to (empty: the source's own); ``held_object`` the object
    the windows were felt through, when the source names it.
    """

    task: str
    sensor: str
    X: np.ndarray
    y: np.ndarray
    geometry: Geometry
    class_names: tuple[str, ...]
    groups: np.ndarray
    rod_length_m: np.ndarray
    source: str
    data_hash: str
    excluded: tuple[str, ...] = ()
    profile: TaskProfile | None = None
    sessions: np.ndarray | None = None
    anchor: str = ""
    held_object: HeldObject | None = None

    @property
    def task_profile(self) -> TaskProfile:
        """The profile the windows were cut with (the task's own when the source gave none)."""
        return self.profile or profile_for(self.task)

    @property
    def session_of(self) -> np.ndarray:
        """The session name of each window (``""`` where the source named none)."""
        if self.sessions is None:
            return np.full(len(self.y), "", dtype="<U1")
        return self.sessions

    @property
    def is_regression(self) -> bool:
        """Whether labels are numbers (tap position)."""
        return not self.class_names

    def subset(self, mask: np.ndarray) -> WindowSet:
        """The windows selected by a boolean mask or index array."""
        return self._replace(
            X=self.X[mask],
            y=self.y[mask],
            groups=self.groups[mask],
            rod_length_m=self.rod_length_m[mask],
            sessions=None if self.sessions is None else self.sessions[mask],
        )

    def crop(self, post_ns: int) -> WindowSet:
        """The same windows cut shorter after the onset (PerceptionError: ``post_ns`` too long)."""
        g = self.geometry
        n = int((g.pre_ns + post_ns) // g.period_ns)
        if not 0 < n <= g.n_samples:
            raise PerceptionError(
                "The 'post_ns' parameter must be in (-pre, "
                f"{g.n_samples * g.period_ns - g.pre_ns}]. Got {post_ns} instead."
            )
        return self._replace(
            X=np.ascontiguousarray(self.X[:, :, :n]), geometry=g._replace(n_samples=n)
        )


def held_object_of(ws: WindowSet) -> HeldObject | None:
    """The object a model trained on ``ws`` was trained on, for its card.

    The set's own ``held_object``; else a rod when every window has a rod length (no length when
    they differ by more than :data:`~ext_sense_perception.online.model_card.LENGTH_TOLERANCE_M`);
    else None.
    """
    if ws.held_object is not None:
        return ws.held_object
    rods = np.asarray(ws.rod_length_m, dtype=np.float64)
    if not rods.size or not np.isfinite(rods).all():
        return None
    if float(rods.max() - rods.min()) > LENGTH_TOLERANCE_M:
        return HeldObject("rod")
    return HeldObject("rod", round(float(np.median(rods)), 4))


def common_held_object(sets: list[WindowSet]) -> HeldObject | None:
    """The object of window sets joined into one: their shared kind (and length), else None."""
    objects = {ws.held_object for ws in sets}
    if None in objects or len({o.kind for o in objects if o is not None}) != 1:
        return None
    return objects.pop() if len(objects) == 1 else HeldObject(next(iter(objects)).kind)


def file_hash(*paths: str | Path) -> str:
    """Short SHA-256 over the bytes of the given files (16 hex digits), for model cards."""
    h = hashlib.sha256()
    for p in sorted(str(q) for q in paths):
        with open(p, "rb") as fh:
            for block in iter(lambda fh=fh: fh.read(1 << 20), b""):
                h.update(block)
    return h.hexdigest()[:16]


def labels_of(y: np.ndarray, regression: bool) -> tuple[np.ndarray, tuple[str, ...]]:
    """Labels in the set's dtype (float64 metres or strings) and the sorted class names."""
    if regression:
        return np.asarray(y, dtype=np.float64), ()
    labels = np.asarray([str(v) for v in y])
    return labels, tuple(sorted({v for v in labels.tolist() if v}))  # "" marks no label


def window_set_of(
    config: WindowConfig,
    windows: list[ContactWindow],
    labels: list[float | str] | np.ndarray,
    source: str,
    data_hash: str,
    *,
    groups: np.ndarray | None = None,
    rod_length_m: np.ndarray | None = None,
    excluded: tuple[str, ...] = (),
    n_channels: int | None = None,
    profile: TaskProfile | None = None,
) -> WindowSet:
    """A window set from windows cut with ``config`` (its task decides the label kind).

    ``groups`` default to the windows' order, ``rod_length_m`` to NaN; ``n_channels`` sizes an
    empty set; ``profile`` (default: the config's) is recorded, since offline cutting changes onset
    source and debounce, which the live graph must not inherit.
    """
    n = len(windows)
    if windows:
        X = np.stack([w.data for w in windows]).astype(np.float32, copy=False)
    else:
        X = np.zeros((0, n_channels or config.n_taxels, config.n_samples()), np.float32)
    y, names = labels_of(np.asarray(labels), regression=config.task.is_regression)
    geometry = Geometry(
        X.shape[1], X.shape[2], config.period_ns, config.pre_ns, config.sensor.label
    )
    return WindowSet(
        config.task.label,
        config.sensor.label,
        X,
        y,
        geometry,
        names,
        np.arange(n) if groups is None else np.asarray(groups),
        np.full(n, np.nan) if rod_length_m is None else np.asarray(rod_length_m, np.float64),
        source,
        data_hash,
        tuple(excluded),
        profile or config.profile,
    )
