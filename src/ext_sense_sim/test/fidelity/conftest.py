"""Synthetic rod-tap captures in the lab's format, with statistics known by construction.

The fixtures hand the writers to the tests (``tap_rows``, ``write_day``, ``noisy_day``).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

T0 = 1616591902.0
PREROLL_BINS = 80
"""Quiet bins before the tap, 2 events each on taxel 3."""
LEAD_EVENTS = 20
"""Events in the bin before the onset: under the threshold max(30, 20 % of 400)."""
ONSET = PREROLL_BINS + 1
PEAK = 400
REST = 100
"""Events in each of the 24 window bins after the onset bin."""
TAXELS = [1] * 20 + [2, 3, 4, 5] + list(range(41, 57))
"""Window events cycle over these: taxel 1 holds half, left 24/40, right 16/40."""
WINDOW_EVENTS = PEAK + 24 * REST


def _tap_rows(scale: int = 1, tail_bins: int = 20) -> list[tuple[int, int, float]]:
    """``(isPos, taxel, t)`` rows of one capture; ``scale`` multiplies the burst's counts."""
    rows: list[tuple[int, int, float]] = []
    for b in range(PREROLL_BINS):
        rows += [(1, 3, b), (0, 3, b)]
    rows += [(1, 7, PREROLL_BINS)] * LEAD_EVENTS
    k = 0
    for b, n in [(ONSET, PEAK), *[(ONSET + i, REST) for i in range(1, 25)]]:
        for _ in range(n * scale):
            rows.append((0 if k % 4 == 0 else 1, TAXELS[k % len(TAXELS)], b))
            k += 1
    last = ONSET + 25 + tail_bins
    rows.append((1, 80, last))
    return [(p, tx, T0 + b / 100) for p, tx, b in rows]


def _write_tact(path: Path, rows: list[tuple[int, int, float]]) -> Path:
    """Write rows as ``isPos taxel 1 t`` lines, ``t`` with two decimals."""
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text("".join(f"{p} {tx} 1 {t:.2f}\n" for p, tx, t in rows))
    return path


def _write_day(folder: Path, rod: int, scales: list[int], missed: int = 0) -> Path:
    """A day's folder with ``rodNN/temp_signal<N>.tact`` captures (plus ``missed`` small ones)."""
    sub = folder / f"rod{rod}"
    for i, scale in enumerate(scales):
        _write_tact(sub / f"temp_signal{i}.tact", _tap_rows(scale))
    for j in range(missed):
        rows = [(1, 5, T0 + b / 100) for b in range(500)]
        _write_tact(sub / f"temp_signal{len(scales) + j}.tact", rows)
    return folder


def _noisy_day(folder: Path, rod: int, n: int, seed: int) -> Path:
    """A day of ``n`` captures whose burst and quiet stretch vary from capture to capture."""
    rng = np.random.default_rng(seed)
    sub = folder / f"rod{rod}"
    for i in range(n):
        rows = _tap_rows(int(rng.integers(1, 4)), tail_bins=int(rng.integers(5, 40)))
        keep = rng.random(len(rows)) > rng.uniform(0.0, 0.3)
        keep[0] = keep[-1] = True
        _write_tact(sub / f"temp_signal{i}.tact", [r for r, k in zip(rows, keep, strict=True) if k])
    return folder


@pytest.fixture
def tap_rows():
    """``tap_rows(scale=1, tail_bins=20)``: the rows of one synthetic capture."""
    return _tap_rows


@pytest.fixture
def write_tact():
    """``write_tact(path, rows)``: write rows in the lab's format."""
    return _write_tact


@pytest.fixture
def write_day():
    """``write_day(folder, rod, scales, missed=0)``: a day's folder of synthetic captures."""
    return _write_day


@pytest.fixture
def noisy_day():
    """``noisy_day(folder, rod, n, seed)``: a day of captures that vary from one to the next."""
    return _noisy_day
