"""Encoder: taxel events -> ACES line samples, signatures summing where they overlap."""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
import numpy.typing as npt

from ext_sense_drivers.aces.bank import SignatureBank, load_bank
from ext_sense_drivers.aces.errors import AcesError
from ext_sense_drivers.aces.sample_clock import ns_to_sample

_BATCH = 65_536
"""Events per vectorised batch (bounds the ``(batch, chips)`` index array to a few MB)."""


class EncodedLine(NamedTuple):
    """Line samples (line units) and each event's start sample (rounded).

    ``n_truncated`` events run past the line's end; ``n_self_overlaps`` come less than one
    signature after their taxel's previous one (indistinguishable; a real NUSkin never sends them).
    """

    samples: npt.NDArray[np.float64]
    start: npt.NDArray[np.int64]
    n_truncated: int
    n_self_overlaps: int


def _check_events(
    t_ns: npt.ArrayLike, taxel: npt.ArrayLike, polarity: npt.ArrayLike, n_taxels: int
) -> tuple[npt.NDArray[np.int64], npt.NDArray[np.int64], npt.NDArray[np.int64]]:
    """Validate the three event arrays and return them as int64."""
    arrays = []
    for name, arr in (("t_ns", t_ns), ("taxel", taxel), ("polarity", polarity)):
        a = np.asarray(arr)
        if a.ndim != 1 or (a.size and not np.issubdtype(a.dtype, np.integer)):
            raise AcesError(
                f"The '{name}' parameter must be a 1-D integer array. "
                f"Got {a.dtype} of shape {a.shape} instead."
            )
        arrays.append(a.astype(np.int64))
    t, k, p = arrays
    if not t.shape == k.shape == p.shape:
        raise AcesError(
            f"The event arrays must have one length. Got t_ns {t.shape}, taxel {k.shape}, "
            f"polarity {p.shape} instead."
        )
    if t.size and t.min() < 0:
        raise AcesError(f"The 't_ns' parameter must be >= 0. Got {int(t.min())} instead.")
    if k.size and (k.min() < 1 or k.max() > n_taxels):
        raise AcesError(
            f"The 'taxel' parameter must be in 1..{n_taxels}. "
            f"Got values in {int(k.min())}..{int(k.max())} instead."
        )
    if p.size and not np.isin(p, (-1, 1)).all():
        raise AcesError(
            f"The 'polarity' parameter must be +1 or -1. Got {sorted(set(p.tolist()) - {-1, 1})}."
        )
    return t, k, p


def encode_line(
    t_ns: npt.ArrayLike,
    taxel: npt.ArrayLike,
    polarity: npt.ArrayLike,
    *,
    bank: SignatureBank | None = None,
    n_samples: int | None = None,
    amplitude: float = 1.0,
    noise_std: float = 0.0,
    rng: np.random.Generator | None = None,
) -> EncodedLine:
    """Sum the signatures of events into line samples (AcesError for a bad argument).

    Events are ``(n,)`` arrays: ``t_ns`` since the line's sample 0, taxel 1..80, polarity +-1.
    ``n_samples`` defaults to just past the last signature; ``amplitude`` (per chip) and
    ``noise_std`` (white Gaussian, from ``rng``, default unseeded) are in line units.
    """
    bank = bank if bank is not None else load_bank()
    t, k, p = _check_events(t_ns, taxel, polarity, bank.n_taxels)
    if not np.isfinite(amplitude):
        raise AcesError(f"The 'amplitude' parameter must be finite. Got {amplitude!r} instead.")
    if not (np.isfinite(noise_std) and noise_std >= 0.0):
        raise AcesError(f"The 'noise_std' parameter must be >= 0. Got {noise_std!r} instead.")
    length = bank.n_chips
    start = ns_to_sample(t, bank.sample_rate_hz)
    if n_samples is None:
        n_samples = int(start.max()) + length if start.size else 0
    if n_samples < 0:
        raise AcesError(f"The 'n_samples' parameter must be >= 0. Got {n_samples} instead.")
    line = np.zeros(n_samples, np.float64)
    chips = bank.chips.astype(np.float64) * amplitude
    offsets = np.arange(length, dtype=np.int64)
    for lo in range(0, start.size, _BATCH):
        s, kk, pp = start[lo : lo + _BATCH], k[lo : lo + _BATCH], p[lo : lo + _BATCH]
        idx = s[:, None] + offsets[None, :]
        val = chips[kk - 1] * pp[:, None]
        inside = idx < n_samples
        line += np.bincount(idx[inside], weights=val[inside], minlength=n_samples)[:n_samples]
    n_truncated = int(np.count_nonzero(start + length > n_samples))
    order = np.lexsort((start, k))
    same = k[order][1:] == k[order][:-1]
    close = np.diff(start[order]) < length
    n_self = int(np.count_nonzero(same & close))
    if noise_std > 0.0 and n_samples:
        gen = rng if rng is not None else np.random.default_rng()
        line += gen.normal(0.0, noise_std, n_samples)
    return EncodedLine(line, start, n_truncated, n_self)
