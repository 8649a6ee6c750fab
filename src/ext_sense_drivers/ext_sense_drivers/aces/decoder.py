"""Streaming ACES line decoder: onset-driven successive cancellation, matched-filter cleanup.

The line is cut into passes at fixed sample positions (so chunking never changes the output).
Each pass looks at a window of ``window`` residual samples and decides the signatures that
start in its first ``window - 2 L + 2`` samples, where every signature that could overlap
them lies inside the window:

1. :class:`~ext_sense_drivers.aces.onset.OnsetDecoder` walks the window in time order,
   correlating with the 80 codes only where a new signature can start, and cancels what it
   accepts (cost grows with events, not samples).
2. If the decided stretch still holds a signature's worth of residual energy, the window goes
   through :class:`~ext_sense_drivers.aces.matched_filter.MatchedFilterSic` (all codes at all
   starts, strongest first); what it finds is added, and a signature it finds that exactly
   negates an onset decision (same taxel and start, other sign) undoes that decision.
3. Decided signatures stay subtracted from the residual; the window slides on.

Cancellation uses one chip amplitude for all signatures (the nominal one, or, by default, an
estimate tracked from the detections and updated between passes), never each detection's own
measured correlation, so the interference in a correlation does not leak into the residual.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from ext_sense_drivers.aces.bank import SignatureBank, load_bank
from ext_sense_drivers.aces.detections import Detections
from ext_sense_drivers.aces.enums import DecodeMode
from ext_sense_drivers.aces.errors import AcesError
from ext_sense_drivers.aces.matched_filter import MatchedFilterSic
from ext_sense_drivers.aces.onset import OnsetDecoder
from ext_sense_drivers.aces.sample_clock import sample_to_ns
from ext_sense_drivers.aces.wire import BYTES_PER_SAMPLE, COUNTS_PER_UNIT, WIRE_DTYPE
from ext_sense_drivers.nuskin.events import EventBlock

DEFAULT_WINDOW = 2048
"""Samples per pass; with 127 chips, 1796 samples (3.5 ms) are decided per pass and no event
waits more than 2048 samples (4.0 ms) after its signature started."""

AMPLITUDE_MEMORY = 16
"""Detections of weight the amplitude estimate carries from the past: each pass moves it by
``n / (n + m)`` of the way to the mean of its ``n`` detections, where ``m`` is the number of
detections so far, at most this (a running mean at first, then an exponential one)."""

AMPLITUDE_RANGE = (0.25, 4.0)
"""The tracked amplitude stays within these multiples of the nominal one."""

_AMPLITUDE_STEP = 0.002
"""Smaller relative changes of the amplitude estimate are not applied (saves work per pass)."""

_REFRESH_RATIO = 0.25
"""A decided stretch one signature long whose residual energy exceeds the noise floor by this
fraction of one signature's energy sends the window through the matched filter."""

MAX_NOISE = 0.6
"""Residual test, absolute part: when even the quietest tenth of a window's decided stretches
keeps more residual than noise of this RMS (chip amplitudes) would leave, the window is noise
or interference beyond what the line is specified for (exact decoding was measured up to 0.4
chip RMS), its correlations are not evidence, and all its detections are withheld."""

_REDO_GAIN = 0.1
"""Relative amplitude error above which a pass with rejected detections is decoded again."""

_REDO_SETTLED = 64
"""Passes are decoded again only until this many detections have measured the amplitude: later
on, a pass with residue is a burst far more often than a gain change (which the tracking
follows), and decoding bursts twice halved the speed."""

_FEED_SLICE = 1 << 20
"""A chunk larger than this many bytes (or half as many samples) is decoded in slices of it, so
that the decoder's own buffers stay bounded however much arrives at once."""

_REFRESH_LIMIT = 8.0
"""Above this many signatures' energy in one decided stretch the matched filter is not run."""

MAX_DEPTH = 16.0
"""Overload gate: a stretch of one signature length whose energy says it carries more than this
many signatures per sample on average (energy per sample / amplitude squared; signatures add
incoherently) is beyond what the line can separate. Its samples are not decoded (set to 0) and
counted. Bursts of 12 signatures started within 0.1 ms (about 9.6 per sample over the stretch,
more where they happen to add up) still decode; 16 did not. Also stops a constant or random
full-scale input (64 and 21)."""

SUSTAINED_SPAN = 4
"""Signature lengths of the overload gate's second, longer stretch."""

MAX_SUSTAINED_DEPTH = 7.0
"""Overload gate on stretches of :data:`SUSTAINED_SPAN` signature lengths: a line that carries
more than this many signatures per sample on average for that long is saturated (a random line
at 95 % busy carries 3, and reaching 7 over four signature lengths is a 1e-4 event there;
a burst of 12 signatures is 3 over such a stretch). Decoding a saturated line only costs time
(the onset decoder's test budget and a matched filter per pass) and produces residue."""

REJECT_RATIO = 0.25
"""Residual test after decoding: a decided stretch one signature long whose residual energy
still exceeds the noise floor by this fraction of one signature's energy was not explained by
the detections around it (a burst too dense to separate: the cancellations left residue that
made more false detections). Committed detections overlapping it are withheld and counted."""


@dataclass(frozen=True)
class LineCounters:
    """What a :class:`LineDecoder` has seen so far.

    Attributes:
        samples: Line samples taken in (including replaced non-finite ones).
        nonfinite_samples: NaN/inf samples replaced by 0 (counted drop; the clock stays right).
        bytes_dropped: Trailing odd byte discarded at :meth:`LineDecoder.flush`.
        detections: Events emitted.
        cancellations: Signatures cancelled, including the matched filter's look-ahead ones
            that are found again in the next pass.
        tested: Code correlations evaluated at single starts (onset tests, matched-filter
            candidates).
        passes: Decoding passes run.
        refreshes: Passes whose residual still held a signature's energy after the onset
            decoder, so that the matched filter ran on them.
        undone: Detections reversed: onset decisions the matched filter found wrong, and
            decisions cancelled by a later one of the other sign at the same taxel and start.
        input_energy: Sum of squared samples taken in, line units squared.
        residual_energy: Sum of squared residual of the decided samples after cancellation;
            near zero on a clean line, so a high ratio to ``input_energy`` means missed events,
            a wrong bank, a gain error, noise or a lost byte (wire samples out of step).
        overload_samples: Samples not decoded because the line carried more than
            :data:`MAX_DEPTH` signatures per sample around them (saturation, bursts beyond
            separation, garbage input).
        rejected: Detections withheld because the residual around them showed the decoding
            there was wrong (see :data:`REJECT_RATIO`).
        unresolved: Estimated signatures the decoder could not resolve: the energy of the
            overloaded samples in units of one signature's energy (overlapping signatures add
            incoherently), plus the rejected detections (the decoder's own count of what it
            could not explain), rounded.
        mean_amplitude: Mean correlation per chip of all detections at acceptance, line
            units (0 before the first): the chip amplitude actually on the line, to compare
            with the decoder's nominal ``amplitude``.
        amplitude_in_use: The chip amplitude the decoder cancels with now (the nominal one, or
            the tracked estimate when ``track_amplitude`` is on).
    """

    samples: int = 0
    nonfinite_samples: int = 0
    bytes_dropped: int = 0
    detections: int = 0
    cancellations: int = 0
    tested: int = 0
    passes: int = 0
    refreshes: int = 0
    undone: int = 0
    input_energy: float = 0.0
    residual_energy: float = 0.0
    overload_samples: int = 0
    rejected: int = 0
    unresolved: int = 0
    mean_amplitude: float = 0.0
    amplitude_in_use: float = 0.0


class LineDecoder:
    """Decode a stream of ACES line samples into taxel events.

    Args:
        bank: Signature bank the line was encoded with (default: the default version).
        threshold: Detection threshold as a fraction of a full match (amplitude x chips), in
            (0, 1); default 0.5.
        amplitude: Nominal chip amplitude of one signature on the line, line units (> 0).
        window: Samples per pass, at least ``4 * chips``: an event is emitted at most this many
            samples after its signature started; larger windows cost less per sample.
        t0_ns: Time of sample 0, added to every event time.
        mode: :attr:`DecodeMode.ONSET` (default) or :attr:`DecodeMode.MATCHED_FILTER`.
        track_amplitude: Follow the chip amplitude measured on the line (starting from
            ``amplitude``, updated after every pass) instead of trusting the nominal one.

    Raises:
        AcesError: A parameter out of range.
    """

    def __init__(
        self,
        bank: SignatureBank | None = None,
        *,
        threshold: float = 0.5,
        amplitude: float = 1.0,
        window: int = DEFAULT_WINDOW,
        t0_ns: int = 0,
        mode: DecodeMode = DecodeMode.ONSET,
        track_amplitude: bool = True,
    ) -> None:
        self.bank = bank if bank is not None else load_bank()
        length = self.bank.n_chips
        if not 0.0 < threshold < 1.0:
            raise AcesError(
                f"The 'threshold' parameter must be in (0, 1). Got {threshold!r} instead."
            )
        if not (np.isfinite(amplitude) and amplitude > 0.0):
            raise AcesError(f"The 'amplitude' parameter must be > 0. Got {amplitude!r} instead.")
        if not isinstance(window, int | np.integer) or window < 4 * length:
            raise AcesError(
                f"The 'window' parameter must be an integer >= {4 * length}. "
                f"Got {window!r} instead."
            )
        self.threshold = float(threshold)
        self.amplitude = float(amplitude)
        self.window = int(window)
        self.t0_ns = int(t0_ns)
        try:
            self.mode = DecodeMode(mode)
        except ValueError as err:
            raise AcesError(
                f"The 'mode' parameter must be one of {[m.name for m in DecodeMode]}. "
                f"Got {mode!r} instead."
            ) from err
        self.track_amplitude = bool(track_amplitude)
        self._length = length
        self._commit = self.window - 2 * length + 2
        self._unit = self.bank.chips.astype(np.float64)
        self._onset = OnsetDecoder(self.bank, self.amplitude, self.threshold)
        self._matched = MatchedFilterSic(self.bank, self.amplitude, self.threshold, self.window)
        self.reset()

    def reset(self) -> None:
        """Forget the stream: sample 0 is the next sample fed; counters restart."""
        self._buf = np.zeros(0, np.float64)
        self._base = 0
        self._odd: bytes = b""
        self._ended = False
        self._c = dict.fromkeys(LineCounters.__dataclass_fields__, 0)
        self._c["input_energy"] = 0.0
        self._c["residual_energy"] = 0.0
        self._unresolved = 0.0
        self._noisy = False
        self._pending = Detections.none()
        self._pending_kept = self._pending
        self._strength = 0.0
        self._strength_n = 0
        self._set_amplitude(self.amplitude)

    def _set_amplitude(self, amplitude: float) -> None:
        """Cancel with ``amplitude`` from now on (both detectors and the residual)."""
        self._amp = amplitude
        self._chips = self._unit * amplitude
        self._onset.set_amplitude(amplitude)
        self._matched.set_amplitude(amplitude)

    def _track(self, strength: float, n: int) -> None:
        """Account a pass's detections; move the amplitude in use toward their mean."""
        memory = min(self._strength_n, AMPLITUDE_MEMORY)
        self._strength += strength
        self._strength_n += n
        if self.track_amplitude and n:
            step = n / (n + memory)
            new = self._amp + step * (strength / n - self._amp)
            lo, hi = AMPLITUDE_RANGE
            new = min(max(new, lo * self.amplitude), hi * self.amplitude)
            if abs(new - self._amp) > _AMPLITUDE_STEP * self._amp:
                self._set_amplitude(new)

    @property
    def counters(self) -> LineCounters:
        """A snapshot of the counters."""
        mean = self._strength / self._strength_n if self._strength_n else 0.0
        return LineCounters(
            **{
                **self._c,
                "unresolved": round(self._unresolved),
                "mean_amplitude": mean,
                "amplitude_in_use": self._amp,
            }
        )

    @property
    def latency_samples(self) -> int:
        """Most samples a signature waits between arriving and being emitted.

        One window, plus one pass more for a signature whose tail runs into the next pass (its
        residual is checked there before it is emitted).
        """
        return self.window + self._commit

    def feed(self, chunk: bytes | bytearray | memoryview | npt.NDArray[np.floating]) -> EventBlock:
        """Take the next piece of the line and return the events decided so far.

        Args:
            chunk: Wire bytes (int16 little-endian, split anywhere, even mid-sample) or a 1-D
                float array of samples in line units. Do not mix the two in one stream while
                a half sample is pending.

        Returns:
            Newly decided events in time order; times are ``t0_ns`` plus the line's sample
            clock since stream start.

        Raises:
            AcesError: Wrong type or shape, integer arrays (send wire counts as bytes), an
                array while half a wire sample is pending, or a stream already flushed.
        """
        if self._ended:
            raise AcesError("This stream was flushed; call reset() before feeding a new one.")
        if isinstance(chunk, bytes | bytearray | memoryview) and len(chunk) > _FEED_SLICE:
            view = memoryview(chunk).cast("B")
            step = _FEED_SLICE
            return EventBlock.concat(
                [self.feed(view[i : i + step]) for i in range(0, len(view), step)]
            )
        if isinstance(chunk, np.ndarray) and chunk.ndim == 1 and chunk.size > _FEED_SLICE // 2:
            step = _FEED_SLICE // 2
            return EventBlock.concat(
                [self.feed(chunk[i : i + step]) for i in range(0, chunk.size, step)]
            )
        samples = self._to_samples(chunk)
        bad = ~np.isfinite(samples)
        if bad.any():
            samples = np.where(bad, 0.0, samples)
            self._c["nonfinite_samples"] += int(bad.sum())
        self._c["samples"] += int(samples.size)
        self._c["input_energy"] += float(np.dot(samples, samples))
        if samples.size:
            self._buf = np.concatenate((self._buf, samples))
        return self._run()

    def flush(self) -> EventBlock:
        """End the stream: decide everything left (zero-padded) and return it.

        A signature cut off by the end of the stream is found if more than ``threshold`` of it
        arrived. A trailing odd byte is counted in ``bytes_dropped``.
        """
        if self._ended:
            return EventBlock.empty()
        if self._odd:
            self._c["bytes_dropped"] += len(self._odd)
            self._odd = b""
        end = self._base + self._buf.size
        blocks = [self._run()]
        while self._base < end:
            pad = self.window - self._buf.size
            if pad > 0:
                self._buf = np.concatenate((self._buf, np.zeros(pad)))
            blocks.append(self._pass(limit=end))
        if self._pending.code.size:  # nothing follows to test their tails against
            blocks.append(self._emit(self._pending))
            self._pending = self._pending_kept = Detections.none()
        self._ended = True
        return EventBlock.concat(blocks)

    def _to_samples(
        self, chunk: bytes | bytearray | memoryview | npt.NDArray[np.floating]
    ) -> npt.NDArray[np.float64]:
        """Turn a chunk into float64 line samples, carrying an odd trailing byte."""
        if isinstance(chunk, bytes | bytearray | memoryview):
            data = self._odd + bytes(chunk)
            cut = len(data) - len(data) % BYTES_PER_SAMPLE
            self._odd = data[cut:]
            return np.frombuffer(data, WIRE_DTYPE, cut // BYTES_PER_SAMPLE).astype(np.float64) / (
                COUNTS_PER_UNIT
            )
        if not isinstance(chunk, np.ndarray):
            raise AcesError(
                "The 'chunk' parameter must be bytes or a float ndarray. "
                f"Got {type(chunk).__name__} instead."
            )
        if chunk.ndim != 1 or not np.issubdtype(chunk.dtype, np.floating):
            raise AcesError(
                "The 'chunk' parameter must be a 1-D float array in line units (wire counts go "
                f"in as bytes). Got {chunk.dtype} of shape {chunk.shape} instead."
            )
        if self._odd:
            raise AcesError("The 'chunk' parameter is an array but half a wire sample is pending.")
        return chunk.astype(np.float64)

    def _run(self) -> EventBlock:
        """Run every pass whose window is complete."""
        blocks = []
        while self._buf.size >= self.window:
            blocks.append(self._pass(limit=None))
        return EventBlock.concat(blocks) if blocks else EventBlock.empty()

    def _pass(self, limit: int | None) -> EventBlock:
        """Decode one window, commit its first part, slide on (``limit``: end of real samples).

        A pass whose residual test withheld detections while they measured an amplitude more
        than :data:`_REDO_GAIN` away from the one in use (before the estimate has settled,
        :data:`_REDO_SETTLED`) is decoded once more with the measured
        amplitude (a gain error leaves residue at every cancellation until it is tracked); the
        second result and its amplitude are kept only if it explains the window clearly better
        (at most half as many withheld, nothing overloaded, something detected): a burst's
        residue must not pull the estimate.
        """
        buf = self._buf
        commit = self._commit if limit is None else min(self._commit, limit - self._base)
        self._c["passes"] += 1
        may_redo = self.track_amplitude and self._strength_n < _REDO_SETTLED
        before = (buf[: self.window].copy() if may_redo else buf, dict(self._c), self._unresolved)
        found, strength, n = self._decode_window(buf, commit)
        rejected = self._c["rejected"] - before[1]["rejected"]
        if rejected and n and not self._noisy:
            # Residue left: either a gain error (decoding again with the measured amplitude
            # explains the window) or more than the line can separate (it does not; then the
            # first result stands and the pass does not move the estimate).
            lo, hi = AMPLITUDE_RANGE
            measured = min(max(strength / n, lo * self.amplitude), hi * self.amplitude)
            redo = may_redo and abs(measured - self._amp) > _REDO_GAIN * self._amp
            if redo:
                first = (buf[: self.window].copy(), dict(self._c), self._unresolved, found)
                old = self._amp
                buf[: self.window] = before[0]
                self._c, self._unresolved = dict(before[1]), before[2]
                self._set_amplitude(measured)
                found, strength, n = self._decode_window(buf, commit)
                if not n or 2 * (self._c["rejected"] - before[1]["rejected"]) > rejected:
                    buf[: self.window] = first[0]
                    self._c, self._unresolved, found = first[1], first[2], first[3]
                    self._set_amplitude(old)
                    redo = False
            if not redo:
                strength, n = 0.0, 0
        elif self.mode is DecodeMode.ONSET and self._onset.exhausted:
            # A window so full of onsets that the test budget ran out is residue or noise more
            # often than a gain error: it may trigger the repeat above, not move the estimate.
            strength, n = 0.0, 0
        decided = buf[: max(commit, 0)]
        self._c["residual_energy"] += float(np.dot(decided, decided))
        # Detections whose signature runs past the decided samples wait for the next pass's
        # residual test over their tail; the ones held by the previous pass that passed it go.
        hold = found.start + self._length > commit
        held = self._pending_kept
        emit = Detections(
            np.concatenate((held.code, found.code[~hold])),
            np.concatenate((held.start, found.start[~hold])),
            np.concatenate((held.sign, found.sign[~hold])),
        )
        self._pending = Detections(
            found.code[hold], found.start[hold] - self._commit, found.sign[hold]
        )
        self._pending_kept = self._pending
        block = self._emit(emit)
        self._buf = buf[self._commit :]
        self._base += self._commit
        self._track(strength, n)
        return block

    def _emit(self, found: Detections) -> EventBlock:
        """Detections (starts relative to the current pass) as events in time order."""
        if found.code.size == 0:
            return EventBlock.empty()
        self._c["detections"] += int(found.code.size)
        order = np.lexsort((found.code, found.start))
        return EventBlock(
            self.t0_ns + sample_to_ns(self._base + found.start[order], self.bank.sample_rate_hz),
            (found.code[order] + 1).astype(np.uint16),
            found.sign[order].astype(np.int8),
            np.zeros(found.code.size, np.uint16),
        )

    def _decode_window(
        self, buf: npt.NDArray[np.float64], commit: int
    ) -> tuple[Detections, float, int]:
        """Gate, detect, cancel and check one window (see :meth:`_pass`).

        Returns:
            The committed detections that passed the residual test, and the summed strength
            and number of detections for the amplitude estimate (0 on an overloaded pass).
        """
        blanked = self._overload(buf, commit)
        trusted = blanked is None
        if self.mode is DecodeMode.MATCHED_FILTER:
            found = self._matched.detect(buf[: self.window], commit)
            self._subtract(buf, found)
            self._count(found)
            strength, n = found.strength, int(found.code.size)
        else:
            found, strength, n = self._onset_pass(buf, commit, refresh=trusted)
        found = self._annihilate(found)
        found = self._reject(buf, found, commit, blanked)
        if not trusted or self._noisy:
            # Detections around overloaded stretches, or in a window whose residual floor is
            # noise beyond specification, measure residue rather than the line's amplitude:
            # such a pass does not move the estimate.
            return found, 0.0, 0
        return found, strength, n

    def _onset_pass(
        self, buf: npt.NDArray[np.float64], commit: int, refresh: bool = True
    ) -> tuple[Detections, float, int]:
        """Onset decoder, then the matched filter if the residual says something was missed.

        The onset decoder also runs (tentatively) up to one signature past ``commit``, so that
        every sample a committed signature touches can be checked for left-over energy; the
        tentative detections are put back afterwards and decided in the next pass. With
        ``refresh`` off (a pass the overload gate blanked) the onset decoder stops at
        ``commit`` and the matched filter does not run: on a saturated line it would cost ten
        times the onset decoder and find residue. The residual test then withholds what the
        window could not explain.

        Returns:
            The committed detections, and their summed strength and number for the amplitude
            estimate.
        """
        length = self._length
        scan = min(commit + length - 2, self.window - length + 1) if refresh else commit
        found = self._onset.decode(buf, scan, settle=commit)
        self._count(found)
        strength, n = found.strength, int(np.count_nonzero(found.start < commit))
        missed = self._missed_energy(buf[: max(scan - 1, 0)])
        later = found.start >= commit
        if later.any():
            self._subtract(
                buf, Detections(found.code[later], found.start[later], -found.sign[later])
            )
            found = Detections(found.code[~later], found.start[~later], found.sign[~later])
        if missed and refresh:
            self._c["refreshes"] += 1
            extra = self._matched.detect(buf[: self.window], commit)
            self._count(extra)
            self._subtract(buf, extra)
            strength += extra.strength
            n += int(extra.code.size)
            found = self._merge(found, extra)
        return found, strength, n

    def _count(self, found: Detections) -> None:
        """Add a detector's work to the counters."""
        self._c["tested"] += found.tested
        self._c["cancellations"] += found.cancellations

    def _merge(self, first: Detections, extra: Detections) -> Detections:
        """Add the matched filter's detections; one that negates an onset decision undoes it."""
        keys = {
            (k, t): i
            for i, (k, t) in enumerate(zip(first.code.tolist(), first.start.tolist(), strict=True))
        }
        drop = np.zeros(first.code.size, dtype=bool)
        add = np.ones(extra.code.size, dtype=bool)
        for j, (k, t, s) in enumerate(
            zip(extra.code.tolist(), extra.start.tolist(), extra.sign.tolist(), strict=True)
        ):
            i = keys.get((k, t))
            if i is not None and not drop[i] and first.sign[i] == -s:
                drop[i] = True
                add[j] = False
        self._c["undone"] += int(drop.sum())
        keep = ~drop
        return Detections(
            np.concatenate((first.code[keep], extra.code[add])),
            np.concatenate((first.start[keep], extra.start[add])),
            np.concatenate((first.sign[keep], extra.sign[add])),
        )

    def _annihilate(self, found: Detections) -> Detections:
        """Collapse detections of one taxel at one start into one (or none, if signs cancel).

        One taxel cannot overlap itself, so a ``+`` and a ``-`` of the same code at the same
        start are a wrong decision and its correction: both go (counted in ``undone``).
        """
        if found.code.size < 2:
            return found
        key = found.code * (1 << 40) + found.start
        ordered = np.sort(key)
        if not (ordered[1:] == ordered[:-1]).any():
            return found
        uniq, first, inverse = np.unique(key, return_index=True, return_inverse=True)
        total = np.zeros(uniq.size, np.int64)
        np.add.at(total, inverse, found.sign)
        self._c["undone"] += int(key.size - np.count_nonzero(total))
        keep = total != 0
        return Detections(
            found.code[first][keep], found.start[first][keep], np.sign(total[keep]).astype(np.int64)
        )

    def _subtract(self, buf: npt.NDArray[np.float64], found: Detections) -> None:
        """Remove detected signatures from the residual line."""
        for k, t, s in zip(
            found.code.tolist(), found.start.tolist(), found.sign.tolist(), strict=True
        ):
            buf[t : t + self._length] -= s * self._chips[k]

    def _stretch_energy(
        self, r: npt.NDArray[np.float64], span: int | None = None
    ) -> npt.NDArray[np.float64]:
        """Energy of every stretch of ``span`` samples (default one signature) in ``r``."""
        span = span or self._length
        cum = np.concatenate(([0.0], np.cumsum(r * r)))
        return cum[span:] - cum[:-span]

    def _overload(self, buf: npt.NDArray[np.float64], commit: int) -> npt.NDArray[np.int64] | None:
        """Blank (and count) the samples before ``commit`` the line cannot separate.

        Every stretch of one signature length that starts before ``commit`` and carries more
        than :data:`MAX_DEPTH` signatures' energy per sample, and every stretch of
        :data:`SUSTAINED_SPAN` lengths above :data:`MAX_SUSTAINED_DEPTH`, marks its samples
        before ``commit``; those are set to 0 so that neither detector works on them. Later samples
        are judged again by the next pass.

        Returns:
            The blanked samples, or None.
        """
        length = self._length
        if commit <= 0:
            return None
        hit = False
        seg = buf[: min(commit + SUSTAINED_SPAN * length - 1, buf.size)]
        if float(np.dot(seg, seg)) <= MAX_DEPTH * self._amp**2 * length:
            return None  # no stretch can hold more than the whole segment
        mark = np.zeros(seg.size + 1, np.int64)
        cum = np.concatenate(([0.0], np.cumsum(seg * seg)))
        for span, depth in ((length, MAX_DEPTH), (SUSTAINED_SPAN * length, MAX_SUSTAINED_DEPTH)):
            if seg.size < span:
                continue
            energy = (cum[span:] - cum[:-span])[:commit]
            starts = np.flatnonzero(energy > depth * self._amp**2 * span)
            if starts.size:
                hit = True
                np.add.at(mark, starts, 1)
                np.add.at(mark, starts + span, -1)
        if not hit:
            return None
        blank = np.flatnonzero(np.cumsum(mark)[:commit] > 0)
        lost = buf[blank]
        self._unresolved += float(np.dot(lost, lost)) / (self._amp**2 * length)
        self._c["overload_samples"] += int(blank.size)
        buf[blank] = 0.0
        return blank

    def _reject(
        self,
        buf: npt.NDArray[np.float64],
        found: Detections,
        commit: int,
        blanked: npt.NDArray[np.int64] | None,
    ) -> Detections:
        """Withhold committed detections in stretches the decoding left unexplained.

        A stretch is unexplained when its residual energy exceeds the noise floor by
        :data:`REJECT_RATIO` of a signature's energy, and every stretch is when the floor
        itself is above :data:`MAX_NOISE`. A detection whose signature overlaps
        samples the overload gate blanked is withheld too: its correlation was measured on
        part of a signature, or on the residue of erased ones.

        Returns:
            ``found`` itself when nothing is withheld, else the kept detections.
        """
        length = self._length
        decided = buf[: max(commit, 0)]
        self._noisy = False
        self._pending_kept = self._pending
        unit = self._amp**2 * length
        if decided.size < length or (
            blanked is None and float(np.dot(decided, decided)) <= REJECT_RATIO * unit
        ):
            return found
        energy = self._stretch_energy(decided)
        if blanked is None and float(energy.max()) <= REJECT_RATIO * unit:
            return found  # nothing above the level, whatever the floor (floor <= max)
        floor = float(np.partition(energy, energy.size // 10)[energy.size // 10])
        self._noisy = floor > MAX_NOISE**2 * unit
        if self._noisy:
            bad = np.ones(energy.size, dtype=bool)
        else:
            bad = energy - floor > REJECT_RATIO * self._amp**2 * length
        if not bad.any() and blanked is None:
            return found
        mark = np.zeros(decided.size + 1, np.int64)
        starts = np.flatnonzero(bad)
        np.add.at(mark, starts, 1)
        np.add.at(mark, starts + length, -1)
        covered = np.cumsum(mark)[: decided.size] > 0
        if blanked is not None:
            covered[blanked[blanked < decided.size]] = True
        cum = np.concatenate(([0], np.cumsum(covered)))
        pending = self._pending
        if pending.code.size:
            hi = np.clip(pending.start + length, 0, decided.size)
            late = cum[hi] > 0  # their tails start this pass, at sample 0
            if late.any():
                self._c["rejected"] += int(late.sum())
                self._unresolved += float(late.sum())
                self._pending_kept = Detections(
                    pending.code[~late], pending.start[~late], pending.sign[~late]
                )
        if found.code.size == 0:
            return found
        # A detection [t, t + L) touches a bad sample if any sample of it (before commit) is.
        lo = np.clip(found.start, 0, decided.size)
        hi = np.clip(found.start + length, 0, decided.size)
        drop = cum[hi] - cum[lo] > 0
        if not drop.any():
            return found
        self._c["rejected"] += int(drop.sum())
        self._unresolved += float(drop.sum())
        keep = ~drop
        return Detections(found.code[keep], found.start[keep], found.sign[keep])

    def _missed_energy(self, decided: npt.NDArray[np.float64]) -> bool:
        """Whether the decided residual still holds a signature's worth of energy somewhere.

        Not when it holds more than :data:`_REFRESH_LIMIT` signatures' worth in one stretch:
        that is a burst the matched filter does not resolve either (the residual test
        withholds it), and running it there cost most of the time on bursty lines.

        Compares the most energetic stretch of one signature length with the quietest tenth
        of the stretches (the noise floor: missed signatures raise it far less than the mean,
        so even a window full of weak missed signatures stands out).
        """
        length = self._length
        if decided.size < length:
            return False
        if float(np.dot(decided, decided)) <= _REFRESH_RATIO * self.amplitude**2 * length:
            return False  # no stretch can hold more than the whole residual
        energy = self._stretch_energy(decided)
        top = float(energy.max()) / (self.amplitude**2 * length)
        if top <= _REFRESH_RATIO:
            return False
        floor = float(np.partition(energy, energy.size // 10)[energy.size // 10])
        excess = top - floor / (self.amplitude**2 * length)
        return _REFRESH_RATIO < excess <= _REFRESH_LIMIT


def decode_line(
    line: bytes | npt.NDArray[np.floating], bank: SignatureBank | None = None, **kwargs: object
) -> EventBlock:
    """Decode a whole line at once (feed plus flush of a fresh :class:`LineDecoder`).

    Args:
        line: Wire bytes or float samples in line units.
        bank: Signature bank (default version if omitted).
        **kwargs: Passed to :class:`LineDecoder`.

    Returns:
        All events in time order.
    """
    dec = LineDecoder(bank, **kwargs)  # type: ignore[arg-type]
    return EventBlock.concat([dec.feed(line), dec.flush()])
