"""The versioned ACES signature bank: one code per taxel, the sign carries the polarity.

Version 1: taxel ``k`` gets row ``k - 1`` of the Gold family of ``x^7 + x^3 + 1`` /
``x^7 + x^3 + x^2 + x + 1`` (127 chips; no 80 of the 129 codes have a better worst aperiodic
correlation than 27/127). 127 chips per 0.25 ms signature make a 508 kHz line, one sample per
chip. A negative event sends ``-code``: 80 matched filters serve 160 signatures. Everything
follows from :data:`BANK_SPECS`; :attr:`SignatureBank.sha256` catches a changed generator.
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass, field
from functools import lru_cache
from typing import NamedTuple

import numpy as np
import numpy.typing as npt

from ext_sense_drivers.aces.errors import AcesError
from ext_sense_drivers.aces.sequences import gold_family, to_chips

N_TAXELS = 80
"""Taxels 1..80 (1..40 left finger, 41..80 right)."""

SIGNATURE_NS = 250_000
"""Signature length of the NUSkin (0.25 ms, 4 kHz event rate per taxel)."""


class BankSpec(NamedTuple):
    """One bank version (Gold pair polynomials as bit masks; ``2**degree - 1`` chips)."""

    version: int
    degree: int
    poly_u: int
    poly_v: int
    n_taxels: int
    signature_ns: int


BANK_SPECS: dict[int, BankSpec] = {
    1: BankSpec(1, 7, 0b10001001, 0b10001111, N_TAXELS, SIGNATURE_NS),
}
"""Every bank version ever published; never edit one, add a new version instead."""

DEFAULT_VERSION = 1

BANK_SHA256: dict[int, str] = {
    1: "6fd7fc650ff4d13031274328187590c11fb859e919af5f0475e671e1446507f3",
}
"""Content hashes as published; the tests check that generation still gives them."""


@dataclass(frozen=True, eq=False)
class SignatureBank:
    """Codes of one bank version and the line clock they imply.

    Attributes:
        version: Bank version.
        chips: Antipodal chips (+1/-1), shape ``(n_taxels, n_chips)`` int8; row ``k`` belongs
            to taxel ``k + 1``; a negative event sends the negated row.
        sample_rate_hz: Line samples (= chips) per second, integer.
        signature_ns: Signature length in integer ns.
        gold_rows: Which rows of the Gold family were kept, shape ``(n_taxels,)``.
    """

    version: int
    chips: npt.NDArray[np.int8]
    sample_rate_hz: int
    signature_ns: int
    gold_rows: npt.NDArray[np.int64] = field(repr=False)

    @property
    def n_taxels(self) -> int:
        """Number of taxels (codes)."""
        return int(self.chips.shape[0])

    @property
    def n_chips(self) -> int:
        """Chips (= line samples) per signature."""
        return int(self.chips.shape[1])

    @property
    def sha256(self) -> str:
        """Hash of version, clock and chips: the bank's identity on the wire and in logs."""
        h = hashlib.sha256()
        h.update(
            f"aces-bank v{self.version} {self.sample_rate_hz} Hz {self.signature_ns} ns;".encode()
        )
        h.update(np.ascontiguousarray(self.chips, dtype=np.int8).tobytes())
        return h.hexdigest()


class CorrelationStats(NamedTuple):
    """Worst correlations of a bank, as fractions of the code length (1.0 = full match).

    Maxima of ``|cross-correlation|`` (periodic, aperiodic) over distinct codes and of the
    autocorrelation sidelobes, and the RMS aperiodic cross-correlation.
    """

    periodic_cross: float
    aperiodic_cross: float
    aperiodic_auto: float
    rms_cross: float


def aperiodic_xcorr(chips: npt.NDArray[np.integer]) -> npt.NDArray[np.float32]:
    """``R[a, b, d + L - 1] = sum_i c_a[i] * c_b[i + d]`` of codes ``(K, L)``: ``(K, K, 2 L - 1)``.

    The matched filter of code ``a`` evaluated ``d`` samples after code ``b`` starts (float32,
    exact integers).
    """
    k, length = chips.shape
    nfft = 1 << int(np.ceil(np.log2(2 * length - 1)))
    spec = np.fft.rfft(chips.astype(np.float64), nfft, axis=1)
    full = np.fft.irfft(spec[:, None, :] * np.conj(spec[None, :, :]), nfft, axis=2)
    # full[a, b, m] = sum_i c_a[i + m] c_b[i] (circular); offset d = -m.
    lags = np.arange(-(length - 1), length)
    out = np.rint(full[:, :, (-lags) % nfft]).astype(np.float32)
    assert out.shape == (k, k, 2 * length - 1)
    return out


@lru_cache(maxsize=4)
def xcorr_table(bank: SignatureBank) -> npt.NDArray[np.float32]:
    """:func:`aperiodic_xcorr` of a bank's codes, computed once per bank (read-only)."""
    table = aperiodic_xcorr(bank.chips)
    table.setflags(write=False)
    return table


def correlation_stats(chips: npt.NDArray[np.integer]) -> CorrelationStats:
    """The worst periodic and aperiodic correlations of antipodal codes ``(K, L)``."""
    k, length = chips.shape
    spec = np.fft.fft(chips.astype(np.float64), axis=1)
    periodic = np.rint(np.fft.ifft(spec[:, None, :] * np.conj(spec[None, :, :]), axis=2).real)
    r = aperiodic_xcorr(chips)
    off_diag = ~np.eye(k, dtype=bool)
    auto = np.abs(r[np.arange(k), np.arange(k)])
    auto[:, length - 1] = 0.0
    cross = r[off_diag]
    return CorrelationStats(
        periodic_cross=float(np.abs(periodic[off_diag]).max() / length),
        aperiodic_cross=float(np.abs(cross).max()) / length,
        aperiodic_auto=float(auto.max()) / length,
        rms_cross=float(np.sqrt(np.mean(cross.astype(np.float64) ** 2)) / length),
    )


@lru_cache(maxsize=4)
def load_bank(version: int = DEFAULT_VERSION) -> SignatureBank:
    """The (cached, read-only) bank of a :data:`BANK_SPECS` version (AcesError if unknown)."""
    spec = BANK_SPECS.get(version)
    if spec is None:
        raise AcesError(
            f"The 'version' parameter must be one of {sorted(BANK_SPECS)}. Got {version!r} instead."
        )
    family = to_chips(gold_family(spec.poly_u, spec.poly_v, spec.degree))
    rows = np.arange(spec.n_taxels, dtype=np.int64)
    chips = family[rows].copy()
    chips.setflags(write=False)
    rows.setflags(write=False)
    n_chips = chips.shape[1]
    rate, rem = divmod(n_chips * 1_000_000_000, spec.signature_ns)
    if rem:
        raise AcesError(
            f"Bank {version}: {n_chips} chips in {spec.signature_ns} ns is no integer rate."
        )
    return SignatureBank(version, chips, rate, spec.signature_ns, rows)
