"""Small synthetic datasets in the simulator's format, built in memory (fast, no simulator)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from ext_sense_runtime.stamps import MS


def synthetic_tap_dataset(
    path: Path,
    n: int = 48,
    seed: int = 0,
    task: str = "tap_localization",
    rod_length_m: float = 0.3,
) -> Path:
    """Taps whose event rhythm on each finger depends on the label (position or class)."""
    rng = np.random.default_rng(seed)
    y = rng.uniform(0.02, 0.28, n)
    onsets = rng.integers(40 * MS, 60 * MS, n)
    ev_trial, ev_t, ev_tax, ev_pol = [], [], [], []
    for i in range(n):
        period = int((2.0 + 10.0 * y[i]) * MS)  # the tap position sets the vibration period
        shift = 2000 * MS if task == "food_identification" else 0  # food windows start 2 s in
        for taxel in range(1, 81, 3):
            times = onsets[i] + shift + np.arange(0, 250 * MS, period) + rng.integers(0, 200_000, 1)
            ev_t.append(times)
            ev_tax.append(np.full(len(times), taxel))
            ev_pol.append(np.where(np.arange(len(times)) % 2 == 0, 1, -1))
            ev_trial.append(np.full(len(times), i))
        noise = np.sort(rng.integers(0, 400 * MS, 20))
        ev_t.append(noise)
        ev_tax.append(rng.integers(1, 81, 20))
        ev_pol.append(rng.choice([-1, 1], 20))
        ev_trial.append(np.full(20, i))
    label_kind = "regression"
    labels: np.ndarray = y
    if task != "tap_localization":
        label_kind = "classification"
        labels = (
            np.where(y > 0.15, "stable", "unstable")
            if task == "handover_stability"
            else np.where(y < 0.1, "apple", np.where(y < 0.2, "tofu", "water"))
        )
    np.savez(
        path,
        task=np.array(task),
        sensor=np.array("nuskin"),
        label_kind=np.array(label_kind),
        y=labels,
        trial=np.arange(n, dtype=np.int32),
        onset_ns=onsets.astype(np.int64),
        rod_length_m=np.full(n, rod_length_m),
        ev_trial=np.concatenate(ev_trial).astype(np.int32),
        ev_t_ns=np.concatenate(ev_t).astype(np.int64),
        ev_taxel=np.concatenate(ev_tax).astype(np.uint16),
        ev_polarity=np.concatenate(ev_pol).astype(np.int8),
        ev_value=np.zeros(sum(len(t) for t in ev_t), np.uint16),
    )
    return path


def synthetic_biotac_dataset(path: Path, n: int = 32, seed: int = 0) -> Path:
    """PAC bursts whose frequency depends on the tap position."""
    rng = np.random.default_rng(seed)
    y = rng.uniform(0.02, 0.28, n)
    period = 454_545
    n_samples = 1100
    onset_idx = 200
    t = np.arange(n_samples) * period * 1e-9
    pac = np.full((n, 1, n_samples), 2000.0)
    for i in range(n):
        f = 100 + 1000 * y[i]
        burst = (
            300 * np.sin(2 * np.pi * f * (t - t[onset_idx])) * np.exp(-(t - t[onset_idx]) / 0.05)
        )
        pac[i, 0, onset_idx:] += burst[onset_idx:]
        pac[i, 0] += rng.normal(0, 2, n_samples)
    np.savez(
        path,
        task=np.array("tap_localization"),
        sensor=np.array("biotac"),
        label_kind=np.array("regression"),
        y=y,
        trial=np.arange(n, dtype=np.int32),
        onset_ns=np.full(n, onset_idx * period, np.int64),
        rod_length_m=np.full(n, 0.3),
        pac=np.clip(pac, 0, 4095).astype(np.uint16),
        pac_t0_ns=np.zeros(n, np.int64),
    )
    return path


@pytest.fixture(scope="session")
def tap_npz(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return synthetic_tap_dataset(tmp_path_factory.mktemp("tap") / "dataset.npz")


@pytest.fixture(scope="session")
def food_npz(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return synthetic_tap_dataset(
        tmp_path_factory.mktemp("food") / "dataset.npz", n=45, task="food_identification"
    )


@pytest.fixture(scope="session")
def handover_npz(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return synthetic_tap_dataset(
        tmp_path_factory.mktemp("handover") / "dataset.npz", n=40, task="handover_stability"
    )


@pytest.fixture(scope="session")
def biotac_npz(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return synthetic_biotac_dataset(tmp_path_factory.mktemp("biotac") / "dataset.npz")


@pytest.fixture(scope="session")
def make_tap_dataset():
    """The synthetic NUSkin dataset writer, for tests that need their own size."""
    return synthetic_tap_dataset
