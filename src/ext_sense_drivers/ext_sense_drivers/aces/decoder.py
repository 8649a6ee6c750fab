"""Streaming ACES line decoder: onset-driven successive cancellation, matched-filter cleanup.

The line is cut into passes at fixed sample positions (chunking never changes the output).
Each pass decides the signatures starting in the first ``window - 2 L + 2`` samples of its
window: the onset decoder cancels them in time order; where a signature's worth of residual
energy is left, the matched filter runs too (and undoes onset decisions it negates).
Cancellation uses one chip amplitude (nominal or tracked), never a detection's own
correlation, so interference does not leak into the residual. The stages live beside this
module: overload gate, residual tests, amplitude tracking, detections, counters.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from ext_sense_drivers.aces.amplitude import (
    REDO_GAIN,
    REDO_SETTLED,
    clamp_amplitude,
    tracked_amplitude,
)
from ext_sense_drivers.aces.bank import SignatureBank, load_bank
from ext_sense_drivers.aces.detections import Detections, annihilate, merge
from ext_sense_drivers.aces.enums import DecodeMode
from ext_sense_drivers.aces.errors import AcesError
from ext_sense_drivers.aces.line_counters import LineCounters
from ext_sense_drivers.aces.matched_filter import MatchedFilterSic
from ext_sense_drivers.aces.onset import OnsetDecoder
from ext_sense_drivers.aces.overload import blank_overload
from ext_sense_drivers.aces.residual import missed_energy, unexplained
from ext_sense_drivers.aces.sample_clock import sample_to_ns
from ext_sense_drivers.aces.wire import chunk_samples
from ext_sense_runtime.records import EventBlock

DEFAULT_WINDOW = 2048
"""Samples per pass (4.0 ms); 1796 of them are decided per pass with 127 chips."""

_FEED_SLICE = 1 << 20
"""Larger chunks (bytes, or half as many samples) are decoded in slices: bounded buffers."""


class LineDecoder:
    """Decode a stream of ACES line samples into taxel events (AcesError for a bad parameter).

    ``threshold``: fraction of a full match, in (0, 1); ``amplitude``: nominal chip amplitude,
    line units; ``window``: samples per pass, >= ``4 * chips`` (larger costs less per sample and
    delays events more); ``t0_ns`` is added to every event time; ``track_amplitude`` follows the
    chip amplitude measured on the line after every pass.
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
        seen = self._strength_n
        self._strength += strength
        self._strength_n += n
        if self.track_amplitude and n:
            new = tracked_amplitude(self._amp, self.amplitude, strength, n, seen)
            if new is not None:
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
        """Most samples a signature waits before it is emitted (one window plus one pass)."""
        return self.window + self._commit

    def feed(self, chunk: bytes | bytearray | memoryview | npt.NDArray[np.floating]) -> EventBlock:
        """The events decided so far, in time order, after the next piece of the line.

        ``chunk`` is wire bytes (split anywhere) or 1-D float samples; AcesError for a bad chunk or
        a flushed stream.
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
        samples, self._odd = chunk_samples(chunk, self._odd)
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

        A cut-off signature is found if more than ``threshold`` of it arrived; a trailing odd
        byte is counted in ``bytes_dropped``.
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

    def _run(self) -> EventBlock:
        """Run every pass whose window is complete."""
        blocks = []
        while self._buf.size >= self.window:
            blocks.append(self._pass(limit=None))
        return EventBlock.concat(blocks) if blocks else EventBlock.empty()

    def _pass(self, limit: int | None) -> EventBlock:
        """Decode one window, commit its first part, slide on (``limit``: end of real samples).

        A pass with withheld detections whose measured amplitude is off by more than
        ``REDO_GAIN`` (before ``REDO_SETTLED``) is decoded again with that amplitude; the redo
        is kept only if it withholds at most half as many and detects something, so a burst's
        residue does not pull the estimate.
        """
        buf = self._buf
        commit = self._commit if limit is None else min(self._commit, limit - self._base)
        self._c["passes"] += 1
        may_redo = self.track_amplitude and self._strength_n < REDO_SETTLED
        before = (buf[: self.window].copy() if may_redo else buf, dict(self._c), self._unresolved)
        found, strength, n = self._decode_window(buf, commit)
        rejected = self._c["rejected"] - before[1]["rejected"]
        if rejected and n and not self._noisy:
            # Residue left: a gain error (a redo explains it) or a burst (the first result
            # stands and the pass does not move the estimate).
            measured = clamp_amplitude(strength / n, self.amplitude)
            redo = may_redo and abs(measured - self._amp) > REDO_GAIN * self._amp
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
            # An exhausted test budget means residue or noise: do not move the estimate.
            strength, n = 0.0, 0
        decided = buf[: max(commit, 0)]
        self._c["residual_energy"] += float(np.dot(decided, decided))
        # Signatures running past the decided samples wait for the next pass's residual test.
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
        """Gate, detect, cancel and check one window.

        Returns:
            The committed detections that passed the residual test, and their summed strength
            and number for the amplitude estimate (0 on an overloaded or noisy pass).
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
        found, undone = annihilate(found)
        self._c["undone"] += undone
        found = self._reject(buf, found, commit, blanked)
        if not trusted or self._noisy:
            # such detections measure residue, not the line's amplitude
            return found, 0.0, 0
        return found, strength, n

    def _onset_pass(
        self, buf: npt.NDArray[np.float64], commit: int, refresh: bool = True
    ) -> tuple[Detections, float, int]:
        """Onset decoder, then the matched filter if the residual says something was missed.

        The onset decoder runs tentatively one signature past ``commit`` so every committed
        signature's samples can be checked; the tentative detections are put back. With
        ``refresh`` off (a blanked pass) it stops at ``commit`` and the matched filter, costly
        and useless on a saturated line, does not run.

        Returns:
            The committed detections, and their summed strength and number.
        """
        length = self._length
        scan = min(commit + length - 2, self.window - length + 1) if refresh else commit
        found = self._onset.decode(buf, scan, settle=commit)
        self._count(found)
        strength, n = found.strength, int(np.count_nonzero(found.start < commit))
        missed = missed_energy(buf[: max(scan - 1, 0)], self.amplitude, length)
        later = found.start >= commit
        if later.any():
            self._subtract(
                buf, Detections(found.code[later], found.start[later], -found.sign[later])
            )
            found = found.select(~later)
        if missed and refresh:
            self._c["refreshes"] += 1
            extra = self._matched.detect(buf[: self.window], commit)
            self._count(extra)
            self._subtract(buf, extra)
            strength += extra.strength
            n += int(extra.code.size)
            found, undone = merge(found, extra)
            self._c["undone"] += undone
        return found, strength, n

    def _count(self, found: Detections) -> None:
        """Add a detector's work to the counters."""
        self._c["tested"] += found.tested
        self._c["cancellations"] += found.cancellations

    def _subtract(self, buf: npt.NDArray[np.float64], found: Detections) -> None:
        """Remove detected signatures from the residual line."""
        for k, t, s in zip(
            found.code.tolist(), found.start.tolist(), found.sign.tolist(), strict=True
        ):
            buf[t : t + self._length] -= s * self._chips[k]

    def _overload(self, buf: npt.NDArray[np.float64], commit: int) -> npt.NDArray[np.int64] | None:
        """Blank and count the samples before ``commit`` the line cannot separate, or None."""
        blanked = blank_overload(buf, commit, self._amp, self._length)
        if blanked is None:
            return None
        self._unresolved += blanked.signatures
        self._c["overload_samples"] += int(blanked.samples.size)
        return blanked.samples

    def _reject(
        self,
        buf: npt.NDArray[np.float64],
        found: Detections,
        commit: int,
        blanked: npt.NDArray[np.int64] | None,
    ) -> Detections:
        """Withhold detections (and held ones of the previous pass) overlapping unexplained samples.

        Returns:
            ``found`` itself when nothing is withheld, else the kept detections.
        """
        length = self._length
        decided = buf[: max(commit, 0)]
        self._pending_kept = self._pending
        self._noisy, cum = unexplained(decided, self._amp, length, blanked)
        if cum is None:
            return found
        pending = self._pending
        if pending.code.size:
            hi = np.clip(pending.start + length, 0, decided.size)
            late = cum[hi] > 0  # their tails start this pass, at sample 0
            if late.any():
                self._c["rejected"] += int(late.sum())
                self._unresolved += float(late.sum())
                self._pending_kept = pending.select(~late)
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
        return found.select(~drop)


def decode_line(
    line: bytes | npt.NDArray[np.floating], bank: SignatureBank | None = None, **kwargs: object
) -> EventBlock:
    """All events of a whole line (wire bytes or samples): feed and flush a :class:`LineDecoder`."""
    dec = LineDecoder(bank, **kwargs)  # type: ignore[arg-type]
    return EventBlock.concat([dec.feed(line), dec.flush()])
