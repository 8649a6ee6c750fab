"""Contact windows to and from ``ext_sense_msgs/ContactWindow`` fields (no rclpy).

Messages are duck-typed: rclpy and rosbags messages have the same field names, so the nodes,
the offline replay and the tests share these conversions.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ext_sense_perception.errors import PerceptionError
from ext_sense_perception.online.window import ContactWindow
from ext_sense_runtime.stamps import stamp_to_ns


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
        "provisional": bool(win.provisional),
        "truncated": bool(win.truncated),
        "degraded": bool(win.degraded),
        "degraded_reason": str(win.degraded_reason),
    }


def window_from_msg(msg: Any) -> ContactWindow:
    """A window from a ``ContactWindow`` message (PerceptionError: shape and data disagree)."""
    shape = tuple(int(s) for s in np.asarray(msg.shape).reshape(-1))
    data = np.asarray(msg.data, dtype=np.float32)
    channels = np.asarray(msg.channels, dtype=np.uint16)
    if len(shape) != 2 or shape[0] * shape[1] != data.size or shape[0] != channels.size:
        raise PerceptionError(
            f"The window's 'shape' must be (n_channels, n_samples) matching 'data' and "
            f"'channels'. Got shape {shape}, {data.size} values, {channels.size} channels instead."
        )
    return ContactWindow(
        task=str(msg.task),
        sensor=str(msg.sensor),
        onset_ns=stamp_to_ns(msg.header.stamp),
        pre_onset_ns=int(msg.pre_onset_ns),
        post_onset_ns=int(msg.post_onset_ns),
        sample_period_ns=int(msg.sample_period_ns),
        channels=channels,
        data=data.reshape(shape),
        provisional=bool(msg.provisional),
        truncated=bool(msg.truncated),
        # absent from messages recorded before the field existed
        degraded=bool(getattr(msg, "degraded", False)),
        degraded_reason=str(getattr(msg, "degraded_reason", "")),
    )
