"""The counters record of the streaming ACES line decoder."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class LineCounters:
    """What a :class:`~ext_sense_drivers.aces.decoder.LineDecoder` has seen so far.

    Attributes:
        samples: Line samples taken in (including replaced non-finite ones).
        nonfinite_samples: NaN/inf samples replaced by 0 (counted drop; the clock stays right).
        bytes_dropped: Trailing odd byte discarded at
            :meth:`~ext_sense_drivers.aces.decoder.LineDecoder.flush`.
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
            :data:`~ext_sense_drivers.aces.overload.MAX_DEPTH` signatures per sample around
            them (saturation, bursts beyond separation, garbage input).
        rejected: Detections withheld because the residual around them showed the decoding
            there was wrong (see :data:`~ext_sense_drivers.aces.residual.REJECT_RATIO`).
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
