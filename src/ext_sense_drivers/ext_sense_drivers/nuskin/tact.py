"""The lab's NUSkin captures: decoded ``<name>.tact`` text and ``<name>_raw.tact`` bytes.

``<name>.tact`` has one line ``flag taxel value t`` per word (``t`` epoch seconds, two
decimals) between the markers ``1 1 1 <t>`` and ``2 2 2 <t>``.
"""

from __future__ import annotations

from pathlib import Path
from typing import NamedTuple

import numpy as np
import numpy.typing as npt

from ext_sense_drivers.nuskin.errors import NuskinError

RAW_SUFFIX = "_raw.tact"


class TactFile(NamedTuple):
    """A decoded ``.tact`` file: ``(n,)`` columns, ``t_s`` and the markers in epoch seconds."""

    flag: npt.NDArray[np.uint8]
    taxel: npt.NDArray[np.uint16]
    value: npt.NDArray[np.uint16]
    t_s: npt.NDArray[np.float64]
    start_s: float
    stop_s: float


def read_tact(path: str | Path) -> TactFile:
    """Read a decoded ``.tact`` file (NuskinError if unreadable or without its markers)."""
    path = Path(path)
    try:
        rows = np.loadtxt(path, dtype=np.float64, ndmin=2)
    except (OSError, ValueError) as err:
        raise NuskinError(f"cannot read .tact file {str(path)!r}: {err}") from err
    if rows.shape[1] != 4 or rows.shape[0] < 2:
        raise NuskinError(
            f"The .tact file {str(path)!r} must have 4 columns and start/stop marker lines. "
            f"Got shape {rows.shape} instead."
        )
    if tuple(rows[0, :3]) != (1, 1, 1) or tuple(rows[-1, :3]) != (2, 2, 2):
        raise NuskinError(
            f"The .tact file {str(path)!r} must start with '1 1 1 t' and end with '2 2 2 t'. "
            f"Got {rows[0, :3].tolist()} and {rows[-1, :3].tolist()} instead."
        )
    body = rows[1:-1]
    return TactFile(
        body[:, 0].astype(np.uint8),
        body[:, 1].astype(np.uint16),
        body[:, 2].astype(np.uint16),
        body[:, 3].copy(),
        float(rows[0, 3]),
        float(rows[-1, 3]),
    )


def decoded_path(raw_path: str | Path) -> Path:
    """The ``.tact`` beside a ``_raw.tact`` capture."""
    raw_path = Path(raw_path)
    if not raw_path.name.endswith(RAW_SUFFIX):
        raise NuskinError(
            f"The 'raw_path' parameter must end in '{RAW_SUFFIX}'. Got {raw_path.name!r} instead."
        )
    return raw_path.with_name(raw_path.name[: -len(RAW_SUFFIX)] + ".tact")


def recorded_rate(raw_path: str | Path) -> float:
    """The capture's average byte rate, bytes/s, from its size and its ``.tact`` markers."""
    raw_path = Path(raw_path)
    tact = read_tact(decoded_path(raw_path))
    span = tact.stop_s - tact.start_s
    if not span > 0:
        raise NuskinError(
            f"The markers of {str(decoded_path(raw_path))!r} must span > 0 s. Got {span} instead."
        )
    return raw_path.stat().st_size / span
