"""The fixed maps every feature family is built from, as matrices (no ROS).

Channel selections, BioTac decimation indices and the time maps (rebinning, sample selection,
the real DFT); ONNX export writes the same matrices.
"""

from __future__ import annotations

from enum import IntEnum

import numpy as np

from ext_sense_perception.errors import PerceptionError

FFT_SCALE_IN = 1.0 / 1000.0  # the public code divides the signal by 1000 before the FFT
FFT_SCALE_OUT = 1.0 / 10.0  # ... and the magnitude by 10 after it


class FeatureKind(IntEnum):
    """The feature sets (``name.lower()`` is the CLI / model-card name)."""

    BASELINE = 0  # NUSkin binned signed counts; BioTac raw PAC
    FFT = 1  # |FFT| of each channel's (binned or decimated) series, paper's scaling
    EST = 2  # Event Spike Tensor style kernel convolution, sampled at equally spaced times
    ACTIVITY = 3  # log1p event activity over time (all taxels) and per taxel over the window
    AUTOENCODER = 4  # 32-d code of an MLP autoencoder over the FFT features

    @classmethod
    def parse(cls, value: str | int | FeatureKind) -> FeatureKind:
        """Kind from its name or alias (a PerceptionError for an unknown one)."""
        if isinstance(value, FeatureKind):
            return value
        if isinstance(value, int):
            return cls(value)
        key = str(value).strip().upper()
        key = {"AE": "AUTOENCODER", "RAW": "BASELINE", "BINNED": "BASELINE", "PAC": "BASELINE"}.get(
            key, key
        )
        try:
            return cls[key]
        except KeyError as err:
            names = ", ".join(k.name.lower() for k in cls)
            raise PerceptionError(
                f"The 'features' parameter must be one of {names}. Got {value!r} instead."
            ) from err


def select_channels(selection: str | None, n_channels: int) -> np.ndarray:
    """Row indices of a channel selection (PerceptionError: unknown, or ids out of range).

    ``selection``: ``None``/``"all"``, ``"left"`` (taxels 1..40), ``"right"`` (41..80),
    ``"taxel:N"`` (1-based) or ``"ids:1,2,5"``.
    """
    if selection is None or selection == "all":
        return np.arange(n_channels)
    half = n_channels // 2
    if selection in ("left", "one_finger"):
        return np.arange(half)
    if selection == "right":
        return np.arange(half, n_channels)
    if selection.startswith(("taxel:", "ids:")):
        try:
            ids = [int(v) for v in selection.split(":", 1)[1].split(",")]
        except ValueError as err:
            raise PerceptionError(
                f"The 'channels' parameter must list integer ids. Got {selection!r} instead."
            ) from err
        idx = np.asarray(ids) - 1
        if idx.size == 0 or idx.min() < 0 or idx.max() >= n_channels:
            raise PerceptionError(
                f"The 'channels' parameter must name ids in 1..{n_channels}. Got {selection!r} "
                "instead."
            )
        return idx
    raise PerceptionError(
        "The 'channels' parameter must be all, left, right, taxel:N or ids:a,b. Got "
        f"{selection!r} instead."
    )


def decimation_indices(n_samples: int, rate_hz: float, base_rate_hz: float) -> np.ndarray:
    """Sorted samples kept when decimating ``base_rate_hz`` to ``rate_hz`` (the paper's spacing)."""
    if not 0 < rate_hz <= base_rate_hz:
        raise PerceptionError(
            f"The 'rate_hz' parameter must be in (0, {base_rate_hz}]. Got {rate_hz!r} instead."
        )
    if rate_hz >= base_rate_hz:
        return np.arange(n_samples)
    keep = max(int(rate_hz / base_rate_hz * n_samples) + 1, 1)
    return np.unique(np.round(np.linspace(0, n_samples - 1, keep)).astype(int))


def rebin_matrix(n_in: int, factor: int, kernel: str = "box") -> np.ndarray:
    """Summing ``factor`` consecutive samples: ``(n_in, n_in // factor)``.

    ``kernel`` ``gauss``: Gaussian-weighted bins instead (:func:`gauss_rebin_matrix`).
    """
    if kernel == "gauss":
        return gauss_rebin_matrix(n_in, factor)
    n_out = n_in // factor
    m = np.zeros((n_in, n_out))
    rows = np.arange(n_out * factor)
    m[rows, rows // factor] = 1.0
    return m


BIN_KERNELS = ("box", "gauss")
"""How samples are summed into feature bins: ``box`` (the paper's) or ``gauss``."""


def gauss_rebin_matrix(n_in: int, factor: int) -> np.ndarray:
    """Gaussian-weighted bins: ``(n_in, n_in // factor)``, one bin's width the Gaussian's sigma.

    A box bin moves whole events between bins when the onset moves by part of a bin, and the
    spectrum with them; smooth weights move the bins a little instead. Each column sums to about
    ``factor``, as a box bin's.
    """
    n_out = n_in // factor
    centres = (np.arange(n_out) + 0.5) * factor
    t = np.arange(n_in) + 0.5
    z = (t[:, None] - centres[None, :]) / factor
    return np.exp(-0.5 * z * z) / np.sqrt(2.0 * np.pi)


def select_matrix(n_in: int, idx: np.ndarray) -> np.ndarray:
    """Picking the samples ``idx``: ``(n_in, len(idx))``."""
    m = np.zeros((n_in, len(idx)))
    m[idx, np.arange(len(idx))] = 1.0
    return m


def dft_matrices(n: int) -> tuple[np.ndarray, np.ndarray]:
    """Real and imaginary parts of the real DFT of ``n`` samples: ``(n, n // 2 + 1)`` each."""
    k = np.arange(n // 2 + 1)
    ang = 2.0 * np.pi * np.outer(np.arange(n), k) / n
    return np.cos(ang), -np.sin(ang)
