"""The message-level core of the window and inference nodes, with no rclpy import.

The nodes only move messages; everything they decide happens here, so that the offline replay
(``ext-sense replay --offline``) drives the very same code on messages decoded from a bag and
two runs on one bag give identical windows and estimates. Messages are duck-typed: rclpy
messages and rosbags messages have the same field names.

- :class:`WindowStage` turns ``TaxelEventBatch`` / ``BioTacFrame`` messages into contact
  windows (:class:`ext_sense_perception.windows.ContactWindow`) through the streaming windower.
- :func:`window_fields` / :func:`window_from_msg` convert windows to and from
  ``ContactWindow`` message fields.
"""

from __future__ import annotations

import os
from collections import OrderedDict
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np

from ext_sense_perception.errors import PerceptionError
from ext_sense_perception.windows import ContactWindow, WindowConfig, make_windower
from ext_sense_runtime.enums import Sensor

NS_PER_S = 1_000_000_000
JOIN_DEPTH = 64
"""BioTac frames of several sensors waiting for their siblings (same sequence) at most."""


def stamp_ns(stamp: Any) -> int:
    """Integer nanoseconds of a ``builtin_interfaces/Time`` (or Duration) message."""
    return int(stamp.sec) * NS_PER_S + int(stamp.nanosec)


class StageCounters(NamedTuple):
    """What a :class:`WindowStage` dropped or joined (monotonic)."""

    batches: int = 0
    events: int = 0
    frames: int = 0
    frames_unjoined: int = 0
    frames_wrong_sensor: int = 0
    bad_messages: int = 0


class WindowStage:
    """Sensor messages in, contact windows out.

    Args:
        config: Window configuration (task, sensor, durations).
        sensor_ids: BioTac sensor slots to join into one multi-channel window (NUSkin: unused).

    Raises:
        PerceptionError: An empty ``sensor_ids`` for BioTac.
    """

    def __init__(self, config: WindowConfig, sensor_ids: tuple[int, ...] = (0,)) -> None:
        self.config = config
        self.sensor_ids = tuple(int(s) for s in sensor_ids)
        if config.sensor is Sensor.BIOTAC and not self.sensor_ids:
            raise PerceptionError("The 'sensor_ids' parameter must name at least one sensor.")
        self.windower = make_windower(config, n_sensors=max(1, len(self.sensor_ids)))
        self._counts = dict.fromkeys(StageCounters._fields, 0)
        self._join: OrderedDict[int, dict[int, Any]] = OrderedDict()
        self.last_data_ns: int | None = None
        """Stream time of the newest data fed, ns (None before any)."""

    @property
    def counters(self) -> StageCounters:
        """Counters since construction."""
        return StageCounters(**self._counts)

    def on_events(self, msg: Any) -> list[ContactWindow]:
        """Feed one ``TaxelEventBatch``; returns the windows that became due.

        A malformed batch (arrays of different lengths, negative offsets) is counted in
        ``bad_messages`` and dropped whole.
        """
        self._counts["batches"] += 1
        t0 = stamp_ns(msg.header.stamp)
        offset = np.asarray(msg.offset_ns, dtype=np.int64)
        taxel = np.asarray(msg.taxel, dtype=np.uint16)
        polarity = np.asarray(msg.polarity, dtype=np.int8)
        if not (len(offset) == len(taxel) == len(polarity)) or (
            len(offset) and int(offset.min()) < 0
        ):
            self._counts["bad_messages"] += 1
            return []
        self._counts["events"] += len(offset)
        t = offset + np.int64(t0)
        end = int(t[-1]) if len(t) else t0
        self.last_data_ns = end if self.last_data_ns is None else max(self.last_data_ns, end)
        return self.windower.feed(t, taxel, polarity)

    def on_frame(self, msg: Any) -> list[ContactWindow]:
        """Feed one ``BioTacFrame``; frames of several sensors are joined by sequence number.

        Frames of sensors not in ``sensor_ids`` are counted and dropped; a sequence whose
        sibling frames never arrive is dropped (counted) once ``JOIN_DEPTH`` newer ones wait.
        """
        self._counts["frames"] += 1
        sid = int(msg.sensor_id)
        if sid not in self.sensor_ids:
            self._counts["frames_wrong_sensor"] += 1
            return []
        seq = int(msg.sequence)
        group = self._join.setdefault(seq, {})
        group[sid] = msg
        if len(group) < len(self.sensor_ids):
            while len(self._join) > JOIN_DEPTH:
                _, dropped = self._join.popitem(last=False)
                self._counts["frames_unjoined"] += len(dropped)
            return []
        del self._join[seq]
        frames = [group[s] for s in self.sensor_ids]
        pac = np.stack([np.asarray(f.pac, dtype=np.float64) for f in frames])
        valid = np.ones_like(pac, dtype=bool)
        for row, frame in enumerate(frames):
            mask = int(frame.invalid_word_mask)
            if mask:
                shifts = 2 * np.arange(pac.shape[1], dtype=np.uint64)  # PAC words are even
                valid[row] = ((np.uint64(mask) >> shifts) & np.uint64(1)) == 0
        t0 = stamp_ns(frames[0].header.stamp)
        period = int(frames[0].pac_sample_period_ns)
        try:
            out = self.windower.feed(t0, pac, period, valid=valid)
        except PerceptionError:
            self._counts["bad_messages"] += 1
            return []
        end = t0 + period * pac.shape[1]
        self.last_data_ns = end if self.last_data_ns is None else max(self.last_data_ns, end)
        return out

    def on_motion_start(self, onset_ns: int) -> bool:
        """Mark an onset known from outside (food: the arm starts moving); False if debounced."""
        return self.windower.mark_onset(int(onset_ns))

    def advance(self, now_ns: int) -> list[ContactWindow]:
        """Declare the stream complete up to ``now_ns`` (no more data before it will come)."""
        return self.windower.advance(int(now_ns))

    def flush(self) -> list[ContactWindow]:
        """Close every pending window (the stream stopped); tails are zero-padded."""
        return self.windower.flush()


def window_fields(win: ContactWindow) -> dict[str, Any]:
    """The ``ContactWindow`` message fields of a window (``stamp_ns`` for the header stamp)."""
    data = np.ascontiguousarray(win.data, dtype=np.float32)
    return {
        "stamp_ns": int(win.onset_ns),
        "task": win.task,
        "sensor": win.sensor,
        "pre_onset_ns": int(win.pre_onset_ns),
        "post_onset_ns": int(win.post_onset_ns),
        "sample_period_ns": int(win.sample_period_ns),
        "shape": np.asarray(data.shape, dtype=np.uint32),
        "channels": np.asarray(win.channels, dtype=np.uint16),
        "data": data.reshape(-1),
        "truncated": bool(win.truncated),
    }


def window_from_msg(msg: Any, final_post_ns: int) -> ContactWindow:
    """Rebuild a window from a ``ContactWindow`` message.

    The message has no provisional flag: a window is provisional when it is not truncated and
    holds less post-onset signal than the task's final window (``final_post_ns``).

    Raises:
        PerceptionError: ``shape`` does not match ``data`` or ``channels``.
    """
    shape = tuple(int(s) for s in np.asarray(msg.shape).reshape(-1))
    data = np.asarray(msg.data, dtype=np.float32)
    channels = np.asarray(msg.channels, dtype=np.uint16)
    if len(shape) != 2 or shape[0] * shape[1] != data.size or shape[0] != channels.size:
        raise PerceptionError(
            f"The window's 'shape' must be (n_channels, n_samples) matching 'data' and "
            f"'channels'. Got shape {shape}, {data.size} values, {channels.size} channels instead."
        )
    post = int(msg.post_onset_ns)
    return ContactWindow(
        task=str(msg.task),
        sensor=str(msg.sensor),
        onset_ns=stamp_ns(msg.header.stamp),
        pre_onset_ns=int(msg.pre_onset_ns),
        post_onset_ns=post,
        sample_period_ns=int(msg.sample_period_ns),
        channels=channels,
        data=data.reshape(shape),
        provisional=(not bool(msg.truncated)) and post < int(final_post_ns),
        truncated=bool(msg.truncated),
    )


def default_model_dir(task: str, sensor: str) -> Path:
    """Where a task's default model bundle lives: ``$EXT_SENSE_MODELS/<task>_<sensor>``.

    ``EXT_SENSE_MODELS`` defaults to ``build/models`` under the working directory; the demo
    trains its model there when it is missing.
    """
    root = Path(os.environ.get("EXT_SENSE_MODELS", Path.cwd() / "build" / "models"))
    return root / f"{task}_{sensor}"


def _get(obj: Any, name: str, default: Any) -> Any:
    value = obj.get(name, default) if isinstance(obj, dict) else getattr(obj, name, default)
    return default if value is None else value


def estimate_fields(
    prediction: Any, window: ContactWindow, model_id: str, compute_latency_ns: int
) -> dict[str, Any]:
    """The ``ContactEstimate`` message fields for a model's prediction on a window.

    Fields the prediction lacks get the message's "does not apply" values (NaN, -1, empty).

    Raises:
        PerceptionError: The prediction holds NaN or inf where a number is required.
    """
    nan = float("nan")
    names = [str(n) for n in _get(prediction, "class_names", [])]
    probs = np.asarray(_get(prediction, "class_probabilities", []), dtype=np.float64).reshape(-1)
    label = str(_get(prediction, "class_label", ""))
    index = int(_get(prediction, "class_index", names.index(label) if label in names else -1))
    position = float(_get(prediction, "tap_position_m", nan))
    if probs.size and not np.isfinite(probs).all():
        raise PerceptionError("The model returned NaN or inf class probabilities.")
    if window.task == "tap_localization" and not np.isfinite(position):
        raise PerceptionError(f"The model returned tap position {position}; expected a number.")
    return {
        "stamp_ns": int(window.onset_ns),
        "task": window.task,
        "sensor": window.sensor,
        "model_id": str(model_id),
        "provisional": bool(window.provisional),
        "post_contact_used_ns": int(window.post_onset_ns),
        "compute_latency_ns": int(compute_latency_ns),
        "tap_position_m": position,
        "tap_position_std_m": float(_get(prediction, "tap_position_std_m", nan)),
        "class_index": index,
        "class_label": label,
        "class_names": names,
        "class_probabilities": probs,
        "stability_probability": float(_get(prediction, "stability_probability", nan)),
    }


def load_bundle(path: Path, backend: str) -> Any:
    """Load a model bundle through the perception package's ``load_model``.

    Raises:
        PerceptionError: Missing or corrupt bundle, or an unknown backend.
    """
    from ext_sense_perception.bundle import load_model

    try:
        return load_model(path, backend=backend)
    except PerceptionError:
        raise
    except Exception as err:  # a corrupt file may surface as anything from the runtimes
        raise PerceptionError(f"Cannot load model bundle {path}: {err}") from err


def model_id_of(model: Any) -> str:
    """The model card id of a loaded bundle (empty when it has none)."""
    for attr in ("model_id", "id"):
        if isinstance(value := getattr(model, attr, None), str):
            return value
    card = getattr(model, "card", None)
    if isinstance(card, dict):
        return str(card.get("id", card.get("model_id", "")))
    return str(getattr(card, "id", getattr(card, "model_id", "")) or "")
