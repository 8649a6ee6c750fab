# ruff: noqa: N806  (X / F for sample matrices, as in scikit-learn)
"""Labelled sets of contact windows built from recordings (no ROS).

Every source becomes a :class:`WindowSet`: windows ``(n, n_channels, n_samples)`` float32 cut
exactly as the online windowers cut them
(:func:`~ext_sense_perception.windows.window_from_recording`),
their labels, and the geometry a model trained on them accepts.
"""

from __future__ import annotations

import hashlib
from pathlib import Path
from typing import NamedTuple

import numpy as np

from ext_sense_perception.errors import PerceptionError
from ext_sense_perception.features import Geometry, refractory_mask
from ext_sense_perception.importers import (
    food_poking_trials,
    load_preprocessed_npz,
    load_sim_dataset,
)
from ext_sense_perception.windows import MS, PAC_PERIOD_NS, WindowConfig, window_from_recording
from ext_sense_runtime.enums import Sensor, Task

DEFAULT_DATASET_BIN_NS = 1 * MS  # offline NUSkin bin: 4x coarser than online, 4x less memory
FOOD_CAPTURE_POST_NS = 3000 * MS  # the real captures end about 3.1 s after the arm starts moving
FOOD_CAPTURE_BIN_NS = 10 * MS  # their timestamps have 10 ms resolution


class WindowSet(NamedTuple):
    """Windows with labels.

    ``X`` is ``(n_windows, n_channels, n_samples)`` float32; ``y`` is float64 metres
    (regression) or ``<U`` class labels; ``groups`` is the trial (or recording) of each window.
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
        )

    def crop(self, post_ns: int) -> WindowSet:
        """The same windows cut shorter after the onset (decision-latency studies).

        Raises:
            PerceptionError: when ``post_ns`` is longer than the windows.
        """
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


def file_hash(*paths: str | Path) -> str:
    """Short SHA-256 over the bytes of the given files (16 hex digits), for model cards."""
    h = hashlib.sha256()
    for p in sorted(str(q) for q in paths):
        with open(p, "rb") as fh:
            for block in iter(lambda fh=fh: fh.read(1 << 20), b""):
                h.update(block)
    return h.hexdigest()[:16]


def _labels(y: np.ndarray, regression: bool) -> tuple[np.ndarray, tuple[str, ...]]:
    if regression:
        return np.asarray(y, dtype=np.float64), ()
    labels = np.asarray([str(v) for v in y])
    return labels, tuple(sorted(set(labels.tolist())))


def offline_window_config(
    task: str | Task, sensor: str | Sensor, bin_ns: int = DEFAULT_DATASET_BIN_NS
) -> WindowConfig:
    """The paper's windows for a task as training sets cut them: ``bin_ns`` NUSkin bins.

    Food windows are 6 s long, so their bins are at least ``FOOD_CAPTURE_BIN_NS`` to keep the
    sets small.

    Args:
        task: Task name or enum.
        sensor: Sensor name or enum.
        bin_ns: NUSkin bin, ns.

    Returns:
        The configuration.
    """
    task = Task.parse(task, PerceptionError)
    if task is Task.FOOD_IDENTIFICATION:
        bin_ns = max(bin_ns, FOOD_CAPTURE_BIN_NS)
    return WindowConfig.for_task(task, sensor, bin_ns=bin_ns)


def from_sim_dataset(
    path: str | Path,
    config: WindowConfig | None = None,
    rate_hz: float | None = None,
    bin_ns: int = DEFAULT_DATASET_BIN_NS,
) -> WindowSet:
    """Windows of the simulator's ``dataset.npz`` at each trial's onset.

    Args:
        path: The dataset.
        config: Windows to cut (default: the paper's for the dataset's task, ``bin_ns`` bins).
        rate_hz: NUSkin: per-taxel refractory drop to this rate before binning (None: none).
        bin_ns: NUSkin bin when ``config`` is None.

    Returns:
        The window set.

    Raises:
        PerceptionError: when the file is malformed.
    """
    d = load_sim_dataset(path)
    task, sensor = (
        Task.parse(d["task"], PerceptionError),
        Sensor.parse(d["sensor"], PerceptionError),
    )
    config = config or offline_window_config(task, sensor, bin_ns)
    onsets = np.asarray(d["onset_ns"], dtype=np.int64)
    n = len(onsets)
    windows = []
    if sensor is Sensor.NUSKIN:
        for key in ("ev_trial", "ev_t_ns", "ev_taxel"):
            if key not in d:
                raise PerceptionError(f"NUSkin dataset {str(path)!r} must hold {key!r}.")
        trial_ids = np.asarray(d["trial"]) if "trial" in d else np.arange(n)
        ev_trial = np.asarray(d["ev_trial"])
        order = np.argsort(ev_trial, kind="stable")
        ev_trial = ev_trial[order]
        t_all = np.asarray(d["ev_t_ns"], dtype=np.int64)[order]
        tax_all = np.asarray(d["ev_taxel"])[order]
        pol_all = np.asarray(d.get("ev_polarity", np.ones(len(order), np.int8)))[order]
        starts = np.searchsorted(ev_trial, trial_ids, side="left")
        ends = np.searchsorted(ev_trial, trial_ids, side="right")
        for i in range(n):
            sl = slice(starts[i], ends[i])
            t, tax, pol = t_all[sl], tax_all[sl], pol_all[sl]
            if len(t) and np.any(np.diff(t) < 0):
                o = np.argsort(t, kind="stable")
                t, tax, pol = t[o], tax[o], pol[o]
            if rate_hz is not None:
                keep = refractory_mask(t, tax, rate_hz)
                t, tax, pol = t[keep], tax[keep], pol[keep]
            windows.append(
                window_from_recording(config, int(onsets[i]), t_ns=t, taxel=tax, polarity=pol)
            )
    else:
        if "pac" not in d:
            raise PerceptionError(f"BioTac dataset {str(path)!r} must hold 'pac'.")
        pac = np.asarray(d["pac"])
        t0 = np.asarray(d.get("pac_t0_ns", np.zeros(n, np.int64)), dtype=np.int64)
        for i in range(n):
            windows.append(
                window_from_recording(config, int(onsets[i]), pac=pac[i], pac_t0_ns=int(t0[i]))
            )
    X = np.stack([w.data for w in windows]) if windows else np.zeros((0, 0, 0), np.float32)
    regression = (
        str(d.get("label_kind", "regression" if task.is_regression else "classification"))
        == "regression"
    )
    y, names = _labels(d["y"], regression)
    geometry = Geometry(X.shape[1], X.shape[2], config.period_ns, config.pre_ns, sensor.label)
    rod = np.asarray(d.get("rod_length_m", np.full(n, np.nan)), dtype=np.float64)
    groups = np.asarray(d.get("trial", np.arange(n)))
    return WindowSet(
        task.label, sensor.label, X, y, geometry, names, groups, rod, str(path), file_hash(path)
    )


def from_food_poking(
    directory: str | Path,
    post_ns: int = FOOD_CAPTURE_POST_NS,
    bin_ns: int = FOOD_CAPTURE_BIN_NS,
    include_empty: bool = False,
    rate_hz: float | None = None,
) -> WindowSet:
    """Windows of the real NUSkin food-poking captures, from the start of the arm's motion.

    The captures end about 3.1 s after the arm starts moving, so the paper's 2 s to 8 s window
    does not fit them: the window runs from the motion start (bag) to ``post_ns`` after it.

    Args:
        directory: ``../shared/data/nuskin_food_poking``.
        post_ns: Window length after the motion start, ns.
        bin_ns: Bin, ns.
        include_empty: Keep the single ``empty`` trial (excluded by default).
        rate_hz: Per-taxel refractory drop to this rate before binning (None: none).

    Returns:
        The window set (``excluded`` names the trials left out).
    """
    recs, excluded = food_poking_trials(directory, include_empty=include_empty)
    config = WindowConfig.for_task(
        Task.FOOD_IDENTIFICATION,
        Sensor.NUSKIN,
        pre_ns=0,
        post_ns=post_ns,
        bin_ns=bin_ns,
        provisional_post_ns=(),
    )
    windows = []
    for rec in recs:
        ev = rec.events
        t, tax, pol = ev.t_ns, ev.taxel, ev.polarity
        if rate_hz is not None:
            keep = refractory_mask(t, tax, rate_hz)
            t, tax, pol = t[keep], tax[keep], pol[keep]
        windows.append(
            window_from_recording(config, rec.motion.start_ns, t_ns=t, taxel=tax, polarity=pol)
        )
    X = np.stack([w.data for w in windows])
    y, names = _labels(np.array([r.label for r in recs]), regression=False)
    geometry = Geometry(X.shape[1], X.shape[2], config.period_ns, config.pre_ns, "nuskin")
    files = [
        p
        for p in sorted(Path(directory).glob("*_zero_*"))
        if p.suffix in (".tact", ".bag") and "_raw" not in p.name
    ]
    files = [p for p in files if p.stem.split("_zero_")[0] != "empty" or include_empty]
    return WindowSet(
        Task.FOOD_IDENTIFICATION.label,
        "nuskin",
        X,
        y,
        geometry,
        names,
        np.arange(len(recs)),
        np.full(len(recs), np.nan),
        str(directory),
        file_hash(*files),
        tuple(excluded),
    )


def from_preprocessed_npz(
    path: str | Path,
    task: str,
    sensor: str,
    frequency_hz: float | None = None,
    rate_hz: float | None = None,
) -> WindowSet:
    """The paper's preprocessed ``.npz`` as a window set.

    NUSkin: 5 ms bins from 50 ms before contact (handover v2 and food: from 0). BioTac: 2200 Hz
    (or ``frequency_hz`` after decimation) from 100 samples before contact.

    Args:
        path: The file.
        task: Task name.
        sensor: Sensor name.
        frequency_hz: BioTac sample rate of the file (None: 2200 Hz).
        rate_hz: NUSkin refractory drop; refused, because the file holds binned counts and the
            drop needs the events themselves (BioTac decimation happens in the features).

    Returns:
        The window set; handover labels are the first label column (``isPos``) as stable/unstable.

    Raises:
        PerceptionError: a NUSkin ``rate_hz``, or a malformed file.
    """
    task_e, sensor_e = Task.parse(task, PerceptionError), Sensor.parse(sensor, PerceptionError)
    if rate_hz is not None and sensor_e is Sensor.NUSKIN:
        raise PerceptionError(
            f"The 'rate_hz' parameter ({rate_hz} Hz) needs NUSkin events, but {str(path)!r} is "
            "the paper's preprocessed file of 5 ms bin counts. Use the .tact recordings "
            "(ext-sense features --data FILE.tact) for the sampling-rate study."
        )
    signals, labels = load_preprocessed_npz(path)
    labels = np.asarray(labels)
    if labels.ndim == 2:
        labels = labels[:, 0]
    if task_e is Task.HANDOVER_STABILITY:
        labels = np.where(labels.astype(float) > 0.5, "stable", "unstable")
    if sensor_e is Sensor.NUSKIN:
        period = 5 * MS if task_e is not Task.FOOD_IDENTIFICATION else 50 * MS
        pre = 50 * MS if task_e is Task.TAP_LOCALIZATION else 0
    else:
        period = PAC_PERIOD_NS if frequency_hz is None else round(1e9 / frequency_hz)
        pre = 100 * period
    y, names = _labels(labels, regression=task_e.is_regression)
    if task_e.is_regression:
        y = y / 100.0 if np.nanmax(np.abs(y)) > 2.0 else y  # the paper's labels are in cm
    geometry = Geometry(signals.shape[1], signals.shape[2], period, pre, sensor_e.label)
    n = len(signals)
    return WindowSet(
        task_e.label,
        sensor_e.label,
        signals,
        y,
        geometry,
        names,
        np.arange(n),
        np.full(n, np.nan),
        str(path),
        file_hash(path),
    )


def load_window_set(
    data: str | Path, task: str | None = None, sensor: str | None = None, **kwargs: object
) -> WindowSet:
    """Any supported source as a window set, chosen by what ``data`` is.

    Args:
        data: A rosbag2 bag (directory, ``.mcap`` or ``.db3``; see
            :func:`ext_sense_perception.bag_windows.window_set_from_bag`), a food-poking
            directory, a simulator ``dataset.npz`` or a preprocessed ``.npz``.
        task: Task (needed for preprocessed files).
        sensor: Sensor (needed for preprocessed files).
        **kwargs: Passed to the source's loader.

    Returns:
        The window set.

    Raises:
        PerceptionError: when the source is not recognised.
    """
    from ext_sense_perception.bag_windows import from_bag, is_bag

    path = Path(data)
    if is_bag(path):
        return from_bag(path, task, sensor, **kwargs)  # type: ignore[arg-type]
    if path.is_dir():
        return from_food_poking(path, **kwargs)  # type: ignore[arg-type]
    if path.suffix == ".npz":
        try:
            with np.load(path, allow_pickle=False) as z:
                files = set(z.files)
        except (OSError, ValueError) as err:
            raise PerceptionError(f"Cannot read {str(path)!r}: {err}") from err
        if "signals" in files:
            if task is None or sensor is None:
                raise PerceptionError(
                    "The 'task' and 'sensor' parameters are needed for a preprocessed npz. Got "
                    "None."
                )
            return from_preprocessed_npz(path, task, sensor, **kwargs)  # type: ignore[arg-type]
        ws = from_sim_dataset(path, **kwargs)  # type: ignore[arg-type]
        if task is not None and Task.parse(task, PerceptionError).label != ws.task:
            raise PerceptionError(
                f"The 'task' parameter must match the dataset's {ws.task!r}. Got {task!r} instead."
            )
        if sensor is not None and Sensor.parse(sensor, PerceptionError).label != ws.sensor:
            raise PerceptionError(
                f"The 'sensor' parameter must match the dataset's {ws.sensor!r}. Got {sensor!r} "
                "instead."
            )
        return ws
    raise PerceptionError(
        "The 'data' parameter must be a bag, a food-poking directory or an .npz dataset. Got "
        f"{str(path)!r} instead."
    )


def from_recording(
    path: str | Path,
    task: str,
    sensor: str,
    essentials: str | Path | None = None,
    config: WindowConfig | None = None,
) -> WindowSet:
    """Windows of one raw recording: the paper's ``.tact`` or BioTac ``.csv``, or a real capture.

    Onsets: from the paper's essentials CSV (``t`` or ``tapped_time`` in epoch seconds, or
    BioTac ``orignal_index``); for a real capture ``.tact`` without essentials, the start of
    the arm's motion from the ``.bag`` beside it. Labels: ``label_y`` (cm, to metres), ``isPos``
    (handover: stable/unstable), or the capture's food name.

    Args:
        path: The recording.
        task: Task name.
        sensor: Sensor name.
        essentials: The paper's essentials CSV (None for real captures).
        config: Windows to cut (default: the paper's for the task).

    Returns:
        The window set.

    Raises:
        PerceptionError: when onsets cannot be found.
    """
    from ext_sense_perception.importers import (
        read_arm_motion,
        read_biotac_csv,
        read_capture_tact,
        read_csv_columns,
        read_paper_tact,
    )

    path = Path(path)
    task_e, sensor_e = Task.parse(task, PerceptionError), Sensor.parse(sensor, PerceptionError)
    labels: np.ndarray
    if essentials is not None:
        cols = read_csv_columns(essentials)
    if sensor_e is Sensor.NUSKIN:
        if essentials is None:
            events = read_capture_tact(path)
            onsets = np.array([read_arm_motion(path.with_suffix(".bag")).start_ns])
            labels = np.array([path.stem.split("_zero_")[0]])
            if config is None:
                config = WindowConfig.for_task(
                    task_e,
                    sensor_e,
                    pre_ns=0,
                    post_ns=FOOD_CAPTURE_POST_NS,
                    bin_ns=FOOD_CAPTURE_BIN_NS,
                    provisional_post_ns=(),
                )
        else:
            events = read_paper_tact(path)
            key = "t" if "t" in cols else "tapped_time"
            if key not in cols:
                raise PerceptionError(
                    f"Essentials {str(essentials)!r} must have a 't' or 'tapped_time' column."
                )
            onsets = (np.round(cols[key] * 1e6).astype(np.int64)) * 1000
            labels = _paper_labels(cols, task_e)
        config = config or WindowConfig.for_task(task_e, sensor_e, bin_ns=DEFAULT_DATASET_BIN_NS)
        wins = [
            window_from_recording(
                config, int(o), t_ns=events.t_ns, taxel=events.taxel, polarity=events.polarity
            )
            for o in onsets
        ]
    else:
        if essentials is None:
            raise PerceptionError(
                "The 'essentials' parameter is needed for a BioTac recording. Got None instead."
            )
        pac, t_ns = read_biotac_csv(path)
        if "orignal_index" in cols:
            idx = cols["orignal_index"].astype(int)
        elif "tapped_time" in cols:
            idx = np.searchsorted(
                t_ns, (np.round(cols["tapped_time"] * 1e6).astype(np.int64)) * 1000
            )
        else:
            raise PerceptionError(
                f"Essentials {str(essentials)!r} must have 'orignal_index' or 'tapped_time'."
            )
        labels = _paper_labels(cols, task_e)
        config = config or WindowConfig.for_task(task_e, sensor_e)
        # sample i of the recording sits at i periods from sample 0: the paper's crops are by index
        wins = [
            window_from_recording(config, int(i) * PAC_PERIOD_NS, pac=pac[None, :], pac_t0_ns=0)
            for i in idx
        ]
    X = np.stack([w.data for w in wins])
    y, names = _labels(labels, regression=task_e.is_regression)
    geometry = Geometry(X.shape[1], X.shape[2], config.period_ns, config.pre_ns, sensor_e.label)
    n = len(X)
    hashed = [path] + ([Path(essentials)] if essentials is not None else [])
    return WindowSet(
        task_e.label,
        sensor_e.label,
        X,
        y,
        geometry,
        names,
        np.arange(n),
        np.full(n, np.nan),
        str(path),
        file_hash(*hashed),
    )


def _paper_labels(cols: dict[str, np.ndarray], task: Task) -> np.ndarray:
    if task is Task.TAP_LOCALIZATION:
        if "label_y" not in cols:
            raise PerceptionError("Tap essentials must have a 'label_y' column (cm).")
        return cols["label_y"] / 100.0
    if task is Task.HANDOVER_STABILITY:
        if "isPos" not in cols:
            raise PerceptionError("Handover essentials must have an 'isPos' column.")
        return np.where(cols["isPos"] > 0.5, "stable", "unstable")
    for key in ("label", "food", "item"):
        if key in cols:
            return cols[key]
    raise PerceptionError("Food essentials must have a 'label' (or 'food') column.")
