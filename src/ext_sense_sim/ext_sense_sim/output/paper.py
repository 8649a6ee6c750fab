"""The paper's own file formats: NUSkin ``.tact`` files with ``essentials.csv``, ``biotac.csv``.

The formats are in docs/simulator.md; trial ``i`` starts at epoch ``BASE_EPOCH_S + i * trial_s``
(a fixed made-up date, so files are reproducible).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

BASE_EPOCH_S = 1_700_000_000.0


def write_tact(arrays: dict[str, np.ndarray], folder: Path, trial_s: float) -> list[Path]:
    """Write the NUSkin ``.tact`` files and ``essentials.csv``; returns the paths."""
    folder.mkdir(parents=True, exist_ok=True)
    bounds = np.searchsorted(arrays["ev_trial"], np.arange(arrays["trial"].size + 1))
    paths, rows = [], ["trial,file,label,onset_s,t0_epoch_s,rod_length_m"]
    for i in range(arrays["trial"].size):
        t0 = BASE_EPOCH_S + i * trial_s
        sl = slice(bounds[i], bounds[i + 1])
        t = t0 + arrays["ev_t_ns"][sl] / 1e9
        is_pos = (arrays["ev_polarity"][sl] > 0).astype(int)
        body = np.column_stack([is_pos, arrays["ev_taxel"][sl], arrays["ev_value"][sl]])
        name = f"trial_{i:04d}.tact"
        lines = [f"1 1 1 {t0:.6f}"]
        lines += [f"{a} {b} {c} {tt:.6f}" for (a, b, c), tt in zip(body.tolist(), t, strict=True)]
        lines.append(f"2 2 2 {t0 + trial_s:.6f}")
        path = folder / name
        path.write_text("\n".join(lines) + "\n")
        paths.append(path)
        y = arrays["y"][i]
        rows.append(
            f"{i},{name},{y},{arrays['onset_ns'][i] / 1e9:.9f},{t0:.6f},{arrays['rod_length_m'][i]}"
        )
    essentials = folder / "essentials.csv"
    essentials.write_text("\n".join(rows) + "\n")
    return [*paths, essentials]


def write_biotac_csv(arrays: dict[str, np.ndarray], path: Path) -> Path:
    """Write ``biotac.csv`` (see module docstring)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    pac = arrays["pac"]
    n_trials, n_sensors, n_pac = pac.shape
    frame = np.arange(n_pac) // 22
    header = "trial,sensor,t_s,pac,pdc,tac,tdc," + ",".join(f"e{i:02d}" for i in range(1, 20))
    with path.open("w") as out:
        out.write(header + "\n")
        for i in range(n_trials):
            t = (arrays["pac_t0_ns"][i] + np.arange(n_pac) * 1e9 / 2200) / 1e9
            for s in range(n_sensors):
                cols = [
                    np.full(n_pac, i),
                    np.full(n_pac, s),
                    np.round(t, 7),
                    pac[i, s],
                    arrays["pdc"][i, s, frame],
                    arrays["tac"][i, s, frame],
                    arrays["tdc"][i, s, frame],
                ]
                table = np.column_stack([*cols, arrays["electrodes"][i, s, frame]])
                np.savetxt(out, table, fmt=["%d", "%d", "%.7f", *["%d"] * 23], delimiter=",")
    return path
