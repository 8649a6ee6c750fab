"""Fast detector: successive cancellation in time order, matched filters only at onsets.

Once every signature that started before sample ``s`` has been cancelled, the residual at
``s`` is the first chip of whatever starts there (+/- one chip amplitude, plus noise) and zero
otherwise. So the detector walks the residual, stops at the first sample above half a chip,
correlates the next ``L`` samples with the 80 codes at that start and the ``back`` starts before
it (in case noise hid the first chip), accepts the best if it passes the threshold, subtracts it,
and looks at the same sample again (two signatures may start together). Work grows with the
number of events, not with the sample rate, which is what makes the decoder fast; the matched
filter in :mod:`ext_sense_drivers.aces.matched_filter` cleans up after it when the residual
says it missed something.
"""

from __future__ import annotations

from bisect import bisect_left

import numpy as np
import numpy.typing as npt

from ext_sense_drivers.aces.bank import SignatureBank
from ext_sense_drivers.aces.detections import Detections

ONSET_RATIO = 0.6
"""A residual sample above this fraction of the chip amplitude is a candidate onset: high
enough that noise of 0.2 chip amplitude (RMS) rarely makes one, low enough that it rarely hides
a first chip; ``back`` covers the first chips it does hide."""

MAX_REPEATS = 4
"""Most signatures accepted at one start before moving on (guards against a loop)."""


class OnsetDecoder:
    """Decode a residual window onset by onset.

    Args:
        bank: The signature bank.
        amplitude: Nominal chip amplitude, line units.
        threshold: Detection threshold, fraction of a full match.
        back: Starts tested before each onset.
    """

    def __init__(
        self, bank: SignatureBank, amplitude: float, threshold: float, back: int = 3
    ) -> None:
        length, k_codes = bank.n_chips, bank.n_taxels
        self._length = length
        self._chips = bank.chips.astype(np.float64) * amplitude
        self._det = threshold * amplitude * length
        self._onset = ONSET_RATIO * amplitude
        self._back = back
        # Row (i, k) holds code k shifted by i: one mat-vec tests the back + 1 earlier starts.
        shifted = np.zeros((back + 1, k_codes, length + back))
        for i in range(back + 1):
            shifted[i, :, i : i + length] = bank.chips
        self._shifted = shifted.reshape((back + 1) * k_codes, length + back)

    def decode(self, r: npt.NDArray[np.float64], commit: int) -> Detections:
        """Detect and cancel, in place, every signature with an onset before ``commit``.

        Args:
            r: Residual line, at least ``commit + L - 1`` samples; accepted signatures are
                subtracted from it.
            commit: Onsets are looked for in ``[0, commit)``.

        Returns:
            The detections in the order found (by start, up to ``back`` samples).
        """
        length, k_codes, back = self._length, self._chips.shape[0], self._back
        chips, det, level = self._chips, self._det, self._onset
        codes: list[int] = []
        starts: list[int] = []
        signs: list[int] = []
        tested = 0
        # Onsets of the untouched line; a cancellation makes [s, s + L) stale, rescanned below.
        static = np.flatnonzero(np.abs(r[:commit]) > level).tolist()
        cursor, dirty, repeats, last = 0, 0, 0, -1
        while cursor < commit:
            p = -1
            if cursor < dirty:
                seg = np.abs(r[cursor : min(dirty, commit)]) > level
                i = int(seg.argmax())
                if seg[i]:
                    p = cursor + i
            if p < 0:
                j = bisect_left(static, max(cursor, dirty))
                if j == len(static):
                    break
                p = static[j]
            corr = chips @ r[p : p + length]
            tested += k_codes
            k = int(np.abs(corr).argmax())
            v = float(corr[k])
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
            codes.append(k)
            starts.append(s)
            signs.append(1 if v > 0 else -1)
            repeats = repeats + 1 if s == last else 1
            last = s
            cursor = s if repeats < MAX_REPEATS else s + 1
            dirty = max(dirty, s + length)
        return Detections(
            np.asarray(codes, np.int64),
            np.asarray(starts, np.int64),
            np.asarray(signs, np.int64),
            tested,
            len(codes),
        )
