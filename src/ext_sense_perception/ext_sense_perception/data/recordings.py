"""Window sets from one raw recording: the paper's ``.tact`` or BioTac ``.csv``, or a capture."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ext_sense_perception.data.importers import (
    read_arm_motion,
    read_biotac_csv,
    read_capture_tact,
    read_csv_columns,
    read_paper_tact,
)
from ext_sense_perception.data.sources import food_capture_config
from ext_sense_perception.data.validation import InputPolicy
from ext_sense_perception.data.window_set import WindowSet, file_hash, window_set_of
from ext_sense_perception.errors import PerceptionError
from ext_sense_perception.online.window import WindowConfig, window_from_recording
from ext_sense_perception.profiles import PAC_PERIOD_NS
from ext_sense_runtime.enums import Sensor, Task


def from_recording(
    path: str | Path,
    task: str,
    sensor: str,
    essentials: str | Path | None = None,
    config: WindowConfig | None = None,
    policy: InputPolicy | None = None,
) -> WindowSet:
    """Windows of one raw recording: the paper's ``.tact`` or BioTac ``.csv``, or a real capture.

    Onsets come from the paper's ``essentials`` CSV (``t`` / ``tapped_time`` epoch seconds, or
    BioTac ``orignal_index``), or for a capture without essentials from the arm bag beside it.
    Labels: ``label_y`` (cm, to metres), ``isPos`` (stable/unstable), or the capture's food name.
    PerceptionError: when onsets cannot be found.
    """
    path = Path(path)
    task_e, sensor_e = Task.parse(task, PerceptionError), Sensor.parse(sensor, PerceptionError)
    labels: np.ndarray
    if essentials is not None:
        cols = read_csv_columns(essentials)
    if sensor_e is Sensor.NUSKIN:
        if essentials is None:
            events = read_capture_tact(path, policy)
            onsets = np.array([read_arm_motion(path.with_suffix(".bag")).start_ns])
            labels = np.array([path.stem.split("_zero_")[0]])
            config = config or food_capture_config()
        else:
            events = read_paper_tact(path, policy)
            key = "t" if "t" in cols else "tapped_time"
            if key not in cols:
                raise PerceptionError(
                    f"Essentials {str(essentials)!r} must have a 't' or 'tapped_time' column."
                )
            onsets = (np.round(cols[key] * 1e6).astype(np.int64)) * 1000
            labels = _paper_labels(cols, task_e)
        config = config or WindowConfig.for_task(task_e, sensor_e)
        wins = [window_from_recording(config, int(o), events=events) for o in onsets]
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
    hashed = [path] + ([Path(essentials)] if essentials is not None else [])
    return window_set_of(config, wins, labels, str(path), file_hash(*hashed))


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
