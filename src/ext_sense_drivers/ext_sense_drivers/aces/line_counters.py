"""The counters record of the streaming ACES line decoder."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class LineCounters:
    """What a :class:`~ext_sense_drivers.aces.decoder.LineDecoder` has seen so far.

    Attributes:
        samples: Line samples taken in (including replaced non-finite ones).
        nonfinite_samples: NaN/inf samples replaced by 0.
        bytes_dropped: Trailing odd byte discarded at ``flush``.
        detections: Events emitted.
        cancellations: Signatures cancelled, including look-ahead ones found again later.
        tested: Code correlations evaluated at single starts.
        passes: Decoding passes run.
        refreshes: Passes on which the matched filter ran after the onset decoder.
        undone: Detections reversed by a later one of the other sign (same taxel and start).
        input_energy: Sum of squared samples taken in, line units squared.
        residual_energy: Sum of squared residual of the decided samples; a high ratio to
            ``input_energy`` means missed events, a wrong bank, a gain error, noise or a lost
            byte.
        overload_samples: Samples the overload gate blanked.
        rejected: Detections withheld by the residual test.
        unresolved: Estimated signatures not resolved: the overloaded energy in signatures,
            plus the rejected detections, rounded.
        mean_amplitude: Mean correlation per chip of all detections, line units (0 before
            the first): the chip amplitude actually on the line.
        amplitude_in_use: The chip amplitude cancelled with now (nominal or tracked).
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
