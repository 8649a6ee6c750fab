"""Fast detector: successive cancellation in time order, matched filters only at onsets.

Once everything that started before sample ``s`` is cancelled, the residual at ``s`` is the
first chip of whatever starts there. So the detector walks to the next onset, correlates the
next ``L`` samples with every code there (and at ``back`` earlier starts), cancels the best
above threshold and looks at the same sample again. Work grows with events, not samples.
"""

from __future__ import annotations

from bisect import bisect_left

import numpy as np
import numpy.typing as npt

from ext_sense_drivers.aces.bank import SignatureBank
from ext_sense_drivers.aces.detections import Detections

ONSET_RATIO = 0.6
"""Candidate onset level, fraction of the chip amplitude: above 0.2-RMS noise, below a first
chip (``back`` covers the first chips noise hides)."""

GATE_SPAN = 16
"""Samples from a candidate onset whose energy is checked before the codes are tested."""

GATE_RATIO = 0.5
"""Onsets whose next :data:`GATE_SPAN` samples hold less than this fraction of a chip's energy
per sample are noise (a real onset brings about one)."""

ACCEPT_MARGIN = 0.15
"""Accept at ``threshold + ACCEPT_MARGIN``: at 0.5 a false acceptance in a dense cluster costs
no residual energy and cascades; the matched filter picks up what this leaves."""

MAX_REPEATS = 4
"""Most signatures accepted at one start before moving on (guards against a loop)."""

MAX_TESTS = 64
"""Most onsets tested per call (:attr:`OnsetDecoder.exhausted`), bounding the work per pass on
noise or garbage; a 95 % busy line tests about 100."""


class OnsetDecoder:
    """Decode a residual window onset by onset, also testing ``back`` starts before each onset.

    Attributes:
        exhausted: Whether the last :meth:`decode` stopped at :data:`MAX_TESTS` onsets.
    """

    def __init__(
        self, bank: SignatureBank, amplitude: float, threshold: float, back: int = 3
    ) -> None:
        length, k_codes = bank.n_chips, bank.n_taxels
        self._length = length
        self._unit = bank.chips.astype(np.float64)
        self._accept = min(threshold + ACCEPT_MARGIN, 0.95)
        self._back = back
        self.exhausted = False
        self.set_amplitude(amplitude)
        # Row (i, k) holds code k shifted by i: one mat-vec tests the back + 1 earlier starts.
        shifted = np.zeros((back + 1, k_codes, length + back))
        for i in range(back + 1):
            shifted[i, :, i : i + length] = bank.chips
        self._shifted = shifted.reshape((back + 1) * k_codes, length + back)

    def set_amplitude(self, amplitude: float) -> None:
        """Use a new chip amplitude (line units) for levels and cancellation."""
        self._chips = self._unit * amplitude
        self._det = self._accept * amplitude * self._length
        self._onset = ONSET_RATIO * amplitude
        self._gate = GATE_RATIO * GATE_SPAN * amplitude**2

    def decode(
        self, r: npt.NDArray[np.float64], commit: int, settle: int | None = None
    ) -> Detections:
        """Detect and cancel in ``r`` every signature with an onset in ``[0, commit)``.

        Only detections starting before ``settle`` (default ``commit``) add to ``strength``; later
        ones are tentative. ``r`` needs at least ``commit + L - 1`` samples.
        """
        length, k_codes, back = self._length, self._chips.shape[0], self._back
        chips, det = self._chips, self._det
        codes: list[int] = []
        starts: list[int] = []
        signs: list[int] = []
        tested = 0
        mags: list[float] = []
        # Onsets of the untouched line; a cancellation makes [s, s + L) stale, rescanned below.
        static = self._onsets(r, 0, commit).tolist()
        cursor, dirty, repeats, last, onsets = 0, 0, 0, -1, 0
        while cursor < commit and onsets < MAX_TESTS:
            p = self._first_onset(r, cursor, min(dirty, commit)) if cursor < dirty else -1
            if p < 0:
                j = bisect_left(static, max(cursor, dirty))
                if j == len(static):
                    break
                p = static[j]
            corr = self._unit @ r[p : p + length]
            tested += k_codes
            onsets += 1
            k, k_neg = int(corr.argmax()), int(corr.argmin())
            v, v_neg = float(corr[k]), float(corr[k_neg])
            if -v_neg > v:
                k, v = k_neg, v_neg
            s = p
            if abs(v) < det:
                lo = p - back
                if lo >= 0:
                    corr = self._shifted @ r[lo : p + length]
                else:
                    corr = self._shifted @ np.concatenate((np.zeros(-lo), r[: p + length]))
                    corr[: -lo * k_codes] = 0.0
                tested += corr.size
                best = int(np.abs(corr).argmax())
                v = float(corr[best])
                if abs(v) < det:
                    cursor = p + 1
                    continue
                i, k = divmod(best, k_codes)
                s = lo + i
            if v > 0:
                r[s : s + length] -= chips[k]
            else:
                r[s : s + length] += chips[k]
            mags.append(abs(v))
            codes.append(k)
            starts.append(s)
            signs.append(1 if v > 0 else -1)
            repeats = repeats + 1 if s == last else 1
            last = s
            cursor = s if repeats < MAX_REPEATS else s + 1
            dirty = max(dirty, s + length)
        self.exhausted = onsets >= MAX_TESTS
        settle = commit if settle is None else settle
        return Detections(
            np.asarray(codes, np.int64),
            np.asarray(starts, np.int64),
            np.asarray(signs, np.int64),
            tested,
            len(codes),
            float(np.asarray(mags)[np.asarray(starts) < settle].sum()) / length if mags else 0.0,
        )

    def _onsets(self, r: npt.NDArray[np.float64], lo: int, hi: int) -> npt.NDArray[np.int64]:
        """Samples in ``[lo, hi)`` above the onset level and followed by enough energy."""
        n = hi - lo
        seg = r[lo : hi + GATE_SPAN - 1]
        cum = np.concatenate(([0.0], np.cumsum(seg * seg)))
        ends = np.minimum(np.arange(GATE_SPAN, GATE_SPAN + n), seg.size)
        energy = cum[ends] - cum[:n]
        return lo + np.flatnonzero((np.abs(seg[:n]) > self._onset) & (energy >= self._gate))

    def _first_onset(self, r: npt.NDArray[np.float64], lo: int, hi: int) -> int:
        """First onset in ``[lo, hi)`` (as :meth:`_onsets`), or -1; cheap when it comes early."""
        while lo < hi:
            above = np.abs(r[lo:hi]) > self._onset
            i = int(above.argmax())
            if not above[i]:
                return -1
            q = lo + i
            head = r[q : q + GATE_SPAN]
            if float(np.dot(head, head)) >= self._gate:
                return q
            lo = q + 1
        return -1
