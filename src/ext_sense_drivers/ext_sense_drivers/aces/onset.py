"""Fast detector: successive cancellation in time order, matched filters only at onsets.

Once every signature that started before sample ``s`` has been cancelled, the residual at
``s`` is the first chip of whatever starts there (+/- one chip amplitude, plus noise) and zero
otherwise. So the detector walks the residual to the next sample above 0.6 chip that is followed
by enough energy, correlates the next ``L`` samples with the 80 codes at that start (and, if
that fails, at the ``back`` starts before it, in case noise hid the first chip), accepts the best
if it passes the threshold, subtracts it, and looks at the same sample again (two signatures may
start together). Work grows with the
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

GATE_SPAN = 16
"""Samples from a candidate onset whose energy is checked before the codes are tested."""

GATE_RATIO = 0.5
"""A real onset brings at least about one chip amplitude squared per sample (more where
signatures overlap); noise of RMS ``sigma`` brings ``sigma**2``. Onsets whose next
:data:`GATE_SPAN` samples hold less than this fraction of a chip's energy per sample are noise."""

ACCEPT_MARGIN = 0.15
"""The onset decoder accepts at ``threshold + ACCEPT_MARGIN`` of a full match. At 0.5 a
cancellation leaves the residual energy unchanged, so a false acceptance at a noise onset in a
dense cluster costs nothing to make and then cascades; the stricter level stops that, and what
it leaves the matched filter (threshold 0.5, strongest first) picks up."""

MAX_REPEATS = 4
"""Most signatures accepted at one start before moving on (guards against a loop)."""

MAX_TESTS = 64
"""Most onsets tested per call (each one or two mat-vecs against the codes, about 25 us). A pass
of the default window at 60 % occupancy tests about 30, at 95 % busy about 100; a line of noise
or garbage that passes every gate stops here (:attr:`OnsetDecoder.exhausted`), so the work per
pass stays bounded (about 4 ms per 3.5 ms pass, plus the matched filter)."""


class OnsetDecoder:
    """Decode a residual window onset by onset.

    Args:
        bank: The signature bank.
        amplitude: Nominal chip amplitude, line units.
        threshold: Detection threshold, fraction of a full match.
        back: Starts tested before each onset.

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
        """Detect and cancel, in place, every signature with an onset before ``commit``.

        Args:
            r: Residual line, at least ``commit + L - 1`` samples; accepted signatures are
                subtracted from it.
            commit: Onsets are looked for in ``[0, commit)``.
            settle: Only detections starting before this sample (default ``commit``) add to
                the returned ``strength``: later ones are tentative, often cut short.

        Returns:
            The detections in the order found (by start, up to ``back`` samples).
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
