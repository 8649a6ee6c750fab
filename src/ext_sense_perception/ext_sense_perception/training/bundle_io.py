# ruff: noqa: N806  (X for the window matrix, as in scikit-learn)
"""Writing model bundles: the ONNX graph, the joblib pipeline and the model card (no ROS).

A bundle also keeps its training windows (``training_windows.npz``) for ``ext-sense
calibrate``. A place is checked first (:func:`check_place`), locked while bundles are made
(:func:`place_lock`), and each bundle is written beside its directory and renamed into it
(:func:`staged_bundle`), so no write leaves a bundle of mixed files.
"""

from __future__ import annotations

import contextlib
import dataclasses
import fcntl
import os
import secrets
import shutil
import tempfile
from collections.abc import Callable, Iterator
from pathlib import Path

import joblib
import numpy as np

from ext_sense_perception.data.window_set import WindowSet
from ext_sense_perception.errors import PerceptionError
from ext_sense_perception.online.model_card import ONNX_FILE, SKLEARN_FILE
from ext_sense_perception.training.fit import TrainedModel
from ext_sense_perception.training.onnx_export import to_onnx_bytes
from ext_sense_runtime.stamps import MS

TRAINING_WINDOWS_FILE = "training_windows.npz"
LOCK_FILE = ".ext_sense_models.lock"
"""The lock file of a place bundles are written into (kept: removing it would race a waiter)."""


def check_place(place: Path, need_bytes: int) -> None:
    """Check ``place`` is writable with ``need_bytes`` free (else a one-line PerceptionError)."""
    try:
        place.mkdir(parents=True, exist_ok=True)
        with tempfile.NamedTemporaryFile(dir=place, prefix=".ext_sense_probe_"):
            pass
        free = shutil.disk_usage(place).free
    except OSError as err:
        raise PerceptionError(f"cannot write into {place}: {err.strerror or err}") from err
    if free < need_bytes:
        raise PerceptionError(
            f"not enough free space in {place}: {free / 2**20:.1f} MB free, "
            f"{need_bytes / 2**20:.0f} MB needed"
        )


@contextlib.contextmanager
def place_lock(place: Path, log: Callable[[str], None] | None = None) -> Iterator[None]:
    """Hold the exclusive ``flock`` of ``place``, waiting (and telling ``log``) for any holder.

    PerceptionError: the lock file cannot be opened.
    """
    try:
        fd = os.open(place / LOCK_FILE, os.O_RDWR | os.O_CREAT, 0o644)
    except OSError as err:
        raise PerceptionError(f"cannot lock {place}: {err.strerror or err}") from err
    try:
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            if log is not None:
                log(f"waiting: another process is writing models into {place}")
            fcntl.flock(fd, fcntl.LOCK_EX)
        except OSError as err:  # a file system without locks
            raise PerceptionError(f"cannot lock {place}: {err.strerror or err}") from err
        yield
    finally:
        os.close(fd)  # closing releases the lock


@contextlib.contextmanager
def staged_bundle(target: Path) -> Iterator[Path]:
    """A fresh directory beside ``target`` to write a bundle into, renamed to ``target`` at the end.

    A bundle at ``target`` is replaced only once the new one is complete, and kept if the block
    fails (PerceptionError: a file could not be written or renamed). What a killed writer left is
    cleared first, so writers must hold :func:`place_lock`.
    """
    tag = f"{os.getpid()}_{secrets.token_hex(4)}"
    staged = target.parent / f".{target.name}.new_{tag}"
    old = target.parent / f".{target.name}.old_{tag}"
    try:
        target.parent.mkdir(parents=True, exist_ok=True)
        for kind in ("new", "old"):
            for left in sorted(target.parent.glob(f".{target.name}.{kind}_*")):
                if kind == "old" and not target.exists():
                    left.rename(target)
                else:
                    shutil.rmtree(left)
        staged.mkdir()  # not mkdtemp: the bundle keeps the umask's mode, readable by others
    except OSError as err:
        raise PerceptionError(f"cannot write the bundle {target}: {err.strerror or err}") from err
    try:
        try:
            yield staged
            if target.exists():
                target.rename(old)
            staged.rename(target)
        except OSError as err:
            if old.exists() and not target.exists():
                old.rename(target)
            raise PerceptionError(
                f"cannot write the bundle {target}: {err.strerror or err}"
            ) from err
    finally:
        shutil.rmtree(staged, ignore_errors=True)
        shutil.rmtree(old, ignore_errors=True)


def save_training_windows(ws: WindowSet, out_dir: str | Path) -> Path:
    """Write the windows a bundle was trained on (compact, compressed) beside its card."""
    X = ws.X
    if np.array_equal(X, np.round(X)) and np.abs(X).max(initial=0) < 2**15:
        X = X.astype(np.int16)  # NUSkin signed counts: exact, and small once compressed
    path = Path(out_dir) / TRAINING_WINDOWS_FILE
    np.savez_compressed(
        path,
        X=X,
        y=ws.y,
        groups=np.asarray(ws.groups),
        rod_length_m=ws.rod_length_m,
        sessions=ws.session_of.astype(str),
    )
    return path


def save_bundle(
    trained: TrainedModel,
    out_dir: str | Path,
    anytime: list[TrainedModel] | tuple = (),
    windows: WindowSet | None = None,
) -> Path:
    """Write ``model.onnx``, ``model.joblib`` and ``model_card.json`` into ``out_dir``.

    Anytime models become bundles in ``out_dir/anytime/post_<ms>ms/``; ``windows`` are kept for
    ``ext-sense calibrate``. A failed ONNX export is raised once the rest is written (the card's
    ``onnx`` null).
    """
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    posts = []
    for part in anytime:
        post_ms = part.card.window.post_ns / MS
        save_bundle(part, out / "anytime" / f"post_{post_ms:g}ms")
        posts.append(post_ms)
    card = dataclasses.replace(trained.card, anytime_post_ms=tuple(posts))
    joblib.dump(trained.pipeline, out / SKLEARN_FILE)
    w = card.window
    error = None
    try:
        (out / ONNX_FILE).write_bytes(to_onnx_bytes(trained.pipeline, w.n_channels * w.n_samples))
    except PerceptionError as err:
        card = dataclasses.replace(card, onnx=None)
        error = err
    if windows is not None:
        save_training_windows(windows, out)
    card.write(out)
    if error is not None:
        raise error
    return out
