"""Window detector: FFT matched filter against every code plus successive cancellation.

Sees every code at every start before deciding, so it is robust to heavy overlap, at 80
inverse FFTs per window. In rounds, every candidate above the threshold that is the strongest
within one signature length (or above :data:`SURE_RATIO`) is accepted and its precomputed
cross-correlation removed from the candidates near it.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt
import scipy.fft
from scipy.ndimage import minimum_filter1d

from ext_sense_drivers.aces.bank import SignatureBank, xcorr_table
from ext_sense_drivers.aces.detections import Detections

CANDIDATE_RATIO = 0.7
"""Candidates are correlations above this fraction of the detection threshold."""

SURE_RATIO = 0.8
"""Candidates above this fraction of a full match are accepted in one round even when close."""

MAX_CANDIDATES = 8192
"""The strongest candidates that enter cancellation (bounds memory and work)."""

MAX_WINNERS = 32
"""The strongest candidates accepted per round (bounds one round's candidate pairs)."""

MAX_ACCEPTED = 128
"""Signatures accepted per window: more than the overload gate lets through for long."""


class MatchedFilterSic:
    """Correlate a ``size``-sample window with the whole bank and cancel successively."""

    def __init__(self, bank: SignatureBank, amplitude: float, threshold: float, size: int) -> None:
        self.size = size
        self._length = bank.n_chips
        self._threshold = threshold
        chips = bank.chips.astype(np.float32)
        self._spec = np.conj(scipy.fft.rfft(chips, size, axis=1)).astype(np.complex64)
        self._xcorr = xcorr_table(bank)
        self.set_amplitude(amplitude)

    def set_amplitude(self, amplitude: float) -> None:
        """Use a new chip amplitude (line units) for thresholds and cancellation."""
        full = amplitude * self._length
        self._amplitude = amplitude
        self._det = self._threshold * full
        self._cand = CANDIDATE_RATIO * self._det
        self._sure = SURE_RATIO * full

    def detect(self, window: npt.NDArray[np.float64], commit: int) -> Detections:
        """The signatures in ``window`` ``(size,)`` starting before ``commit``, by start."""
        n, length = self.size, self._length
        spec = scipy.fft.rfft(window.astype(np.float32), n)
        corr = scipy.fft.irfft(spec[None, :] * self._spec, n, axis=1)[:, : n - length + 1]
        peak = np.maximum(corr.max(axis=0), -corr.min(axis=0))
        cols = np.flatnonzero(peak > self._cand)
        sub = corr[:, cols]
        ck, cj = np.nonzero(np.abs(sub) > self._cand)
        cv = sub[ck, cj].astype(np.float64)
        ct = cols[cj]
        if cv.size > MAX_CANDIDATES:
            strongest = np.argpartition(-np.abs(cv), MAX_CANDIDATES - 1)[:MAX_CANDIDATES]
            ck, ct, cv = ck[strongest], ct[strongest], cv[strongest]
        order = np.argsort(ct, kind="stable")
        ck, ct, cv = ck[order].astype(np.int64), ct[order].astype(np.int64), cv[order]
        k, t, s, mag, steps = self._cancel(ck, ct, cv)
        keep = t < commit
        order = np.argsort(t[keep], kind="stable")
        return Detections(
            k[keep][order],
            t[keep][order],
            s[keep][order],
            int(ck.size),
            steps,
            float(mag[keep].sum()) / self._length,
        )

    def _cancel(
        self, ck: npt.NDArray[np.int64], ct: npt.NDArray[np.int64], cv: npt.NDArray[np.float64]
    ) -> tuple[
        npt.NDArray[np.int64],
        npt.NDArray[np.int64],
        npt.NDArray[np.int64],
        npt.NDArray[np.float64],
        int,
    ]:
        """Rounds of cancellation over candidates sorted by start.

        Returns:
            Code, start, sign and ``|correlation|`` of every accepted candidate, and the steps.
        """
        length = self._length
        active = np.ones(ck.size, dtype=bool)
        acc: list[npt.NDArray[np.int64]] = []
        signs: list[npt.NDArray[np.int64]] = []
        mags: list[npt.NDArray[np.float64]] = []
        steps = 0
        while steps < MAX_ACCEPTED:
            mag = np.where(active, np.abs(cv), 0.0)
            elig = np.flatnonzero(mag >= self._det)
            if elig.size == 0:
                break
            te, me = ct[elig], mag[elig]
            # Rank 0 = strongest (ties: first index). A candidate wins when no eligible one
            # within one signature length ranks better: a running minimum of the best rank
            # per start, over starts t - L + 1 .. t + L - 1 (memory linear in the window).
            rank = np.lexsort((elig, -me))
            pos = np.empty_like(rank)
            pos[rank] = np.arange(rank.size)
            span = int(te[-1]) + 1
            best = np.full(span, rank.size, np.int64)
            np.minimum.at(best, te, pos)
            nearest = minimum_filter1d(best, 2 * length - 1, mode="constant", cval=rank.size)
            win = elig[(pos == nearest[te]) | (me >= self._sure)]
            if win.size > MAX_WINNERS:
                win = np.sort(win[np.argsort(-np.abs(cv[win]), kind="stable")[:MAX_WINNERS]])
            win = win[: MAX_ACCEPTED - steps]
            acc.append(win)
            signs.append(np.where(cv[win] > 0, 1, -1))
            mags.append(np.abs(cv[win]))
            active[win] = False
            steps += int(win.size)
            # Every candidate within one signature length of a winner, as flat pairs.
            lo = np.searchsorted(ct, ct[win] - length + 1, "left")
            hi = np.searchsorted(ct, ct[win] + length, "left")
            counts = hi - lo
            owner = np.repeat(np.arange(win.size), counts)
            idx = np.arange(int(counts.sum())) - np.repeat(np.cumsum(counts) - counts, counts)
            idx += np.repeat(lo, counts)
            w = win[owner]
            sign = np.where(cv[w] > 0, self._amplitude, -self._amplitude)
            delta = sign * self._xcorr[ck[idx], ck[w], ct[idx] - ct[w] + length - 1]
            cv = cv - np.bincount(idx, weights=delta, minlength=cv.size)
        if not acc:
            empty = np.empty(0, np.int64)
            return empty, empty, empty, np.empty(0), 0
        sel = np.concatenate(acc)
        sign = np.concatenate(signs).astype(np.int64)
        return ck[sel], ct[sel], sign, np.concatenate(mags), steps
