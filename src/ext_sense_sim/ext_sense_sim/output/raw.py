"""Raw device byte streams of a run: ``raw/<device>.bin`` and when each write happened.

Replaying the ``.bin`` at the times of ``raw/<device>_chunks.csv`` reproduces the link.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np


def write_raw(streams: list, device: str, folder: Path, trial_ns: int) -> list[Path]:
    """Write ``<device>.bin`` and ``<device>_chunks.csv`` from per-trial wire streams."""
    folder.mkdir(parents=True, exist_ok=True)
    bin_path, csv_path = folder / f"{device}.bin", folder / f"{device}_chunks.csv"
    offset = 0
    with bin_path.open("wb") as data, csv_path.open("w") as index:
        index.write("offset,length,t_ns,trial\n")
        for trial, stream in enumerate(streams):
            data.write(stream.data)
            lengths = np.diff(stream.offsets)
            starts = offset + stream.offsets[:-1]
            t = stream.t_ns + trial * trial_ns
            rows = np.column_stack([starts, lengths, t, np.full(t.size, trial)])
            np.savetxt(index, rows, fmt="%d", delimiter=",")
            offset += len(stream.data)
    return [bin_path, csv_path]
