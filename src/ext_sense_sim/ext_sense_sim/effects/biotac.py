"""BioTac transduction: finger pressure to PAC at 2200 Hz and the slow channels at 100 Hz.

Model. Each finger's fluid pressure is the mean of its 40 taxel pressures. PAC: that pressure
through a second-order band-pass of ``pac_band_hz`` about ``pac_mid``, plus noise, sampled at
2200 Hz (the simulation rate a multiple) and 12-bit. PDC: the pressure through a 10 Hz low-pass;
TAC and TDC: rest temperatures plus noise (TDC drifting); each of the 19 electrodes: a rest value
minus a gain times the Gaussian-weighted pressure around its place. The slow channels are sampled
at each 10 ms frame's first PAC sample; the frame grid starts at a random PAC phase.
"""

from __future__ import annotations

from typing import Any, ClassVar

import numpy as np
from scipy.signal import butter, lfilter, lfilter_zi

from ext_sense_sim.effects.base import Effect, Signals, TimeBase
from ext_sense_sim.effects.grasp import PER_FINGER, lattice
from ext_sense_sim.errors import SceneError

PAC_RATE_HZ = 2200
PAC_PER_FRAME = 22
N_ELECTRODES = 19


def electrode_layout(pitch_m: float = 0.003) -> tuple[np.ndarray, np.ndarray]:
    """Axial and lateral places of the 19 electrodes on the fingertip (a 5-4-5-5 pattern)."""
    rows = ((-3.0, 5), (-1.0, 4), (1.0, 5), (3.0, 5))
    u, c = [], []
    for row, count in rows:
        for j in range(count):
            u.append(row * pitch_m)
            c.append((j - (count - 1) / 2) * pitch_m)
    return np.array(u), np.array(c)


def to_adc(x: np.ndarray) -> np.ndarray:
    """Round and clip to the 12-bit range, as uint16."""
    return np.clip(np.round(x), 0, 4095).astype(np.uint16)


class BiotacTransduction(Effect):
    """Pressure to BioTac channels (see module docstring). Gives ``biotac``."""

    name = "biotac_transduction"
    needs = ("taxel_pressure",)
    gives = ("biotac",)
    defaults: ClassVar[dict[str, Any]] = {
        "pac_band_hz": [10.0, 1040.0],
        "pac_counts_per_pa": 0.02,
        "pac_mid": 2048.0,
        "pac_noise_counts": 2.0,
        "pdc_counts_per_pa": 0.004,
        "pdc_rest": 1800.0,
        "tac_rest": 2000.0,
        "tdc_rest": 2400.0,
        "slow_noise_counts": 1.5,
        "electrode_rest": 3000.0,
        "electrode_counts_per_pa": 0.004,
    }

    def setup(self) -> None:
        """Check the parameters and precompute what every batch shares."""
        ratio = self.context.rate_hz / PAC_RATE_HZ
        if abs(ratio - round(ratio)) > 1e-9 or round(ratio) < 1:
            raise SceneError(
                f"Effect '{self.name}' needs a simulation rate that is a multiple of 2200 Hz. "
                f"Got {self.context.rate_hz} Hz instead."
            )
        self.decimate = round(ratio)
        band = self.params["pac_band_hz"]
        lo, hi = float(band[0]), min(float(band[1]), 0.45 * self.context.rate_hz)
        self.pac_b, self.pac_a = butter(2, [lo, hi], btype="bandpass", fs=self.context.rate_hz)
        self.dc_b, self.dc_a = butter(2, 10.0, fs=self.context.rate_hz)
        u, c = lattice(0.003)
        eu, ec = electrode_layout()
        w = np.exp(
            -0.5 * (((u[None] - eu[:, None]) ** 2 + (c[None] - ec[:, None]) ** 2) / 0.003**2)
        )
        self.electrode_weights = w / w.sum(axis=1, keepdims=True)  # (19, 40)

    def run(self, signals: Signals, time: TimeBase, rng: np.random.Generator) -> None:
        """Give ``biotac``: a dict of the dataset's BioTac arrays for this batch."""
        pressure = signals.need("taxel_pressure", self.name)
        n = time.n_trials
        fingers = pressure.reshape(n, 2, PER_FINGER, -1).astype(np.float64)
        fluid = fingers.mean(axis=2)  # (n, 2, T)
        n_frames = (time.n_samples - self.decimate) // (self.decimate * PAC_PER_FRAME)
        if n_frames < 1:
            raise SceneError(f"Effect '{self.name}': trials must last at least one 10 ms frame.")
        phase = rng.integers(0, self.decimate, size=n)
        pac_idx = phase[:, None] + self.decimate * np.arange(n_frames * PAC_PER_FRAME)[None, :]
        rows = np.arange(n)[:, None, None]
        ac = lfilter(self.pac_b, self.pac_a, fluid - fluid[..., :1], axis=-1)
        pac = (
            self.scalar("pac_mid")
            + self.scalar("pac_counts_per_pa")
            * ac[rows, np.arange(2)[None, :, None], pac_idx[:, None, :]]
        )
        pac += self.scalar("pac_noise_counts", 0.0) * rng.standard_normal(pac.shape)
        frame_idx = pac_idx[:, ::PAC_PER_FRAME]  # (n, n_frames)
        zi = lfilter_zi(self.dc_b, self.dc_a)
        dc, _ = lfilter(self.dc_b, self.dc_a, fluid, axis=-1, zi=zi * fluid[..., :1])
        sel = (rows, np.arange(2)[None, :, None], frame_idx[:, None, :])
        noise = self.scalar("slow_noise_counts", 0.0)
        pdc = self.scalar("pdc_rest") + self.scalar("pdc_counts_per_pa") * dc[sel]
        slow_shape = (n, 2, n_frames)
        tac = self.scalar("tac_rest") + noise * rng.standard_normal(slow_shape)
        drift = np.cumsum(0.05 * rng.standard_normal(slow_shape), axis=-1)
        tdc = self.scalar("tdc_rest") + drift + noise * rng.standard_normal(slow_shape)
        local = np.einsum("ej,bfjs->bfse", self.electrode_weights, fingers[..., frame_idx[0]])
        electrodes = self.scalar("electrode_rest") - self.scalar("electrode_counts_per_pa") * local
        electrodes += noise * rng.standard_normal(electrodes.shape)
        signals["biotac"] = {
            "pac": to_adc(pac),
            "pac_t0_ns": np.round(phase * 1e9 / time.rate_hz).astype(np.int64),
            "pdc": to_adc(pdc + noise * rng.standard_normal(slow_shape)),
            "tac": to_adc(tac),
            "tdc": to_adc(tdc),
            "electrodes": to_adc(electrodes),
        }
