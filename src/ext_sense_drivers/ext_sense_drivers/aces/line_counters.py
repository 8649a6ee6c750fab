"""The counters record of the streaming ACES line decoder."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class LineCounters:
    """What a :class:`~ext_sense_drivers.aces.decoder.LineDecoder` has seen so far.

    ``nonfinite_samples`` were replaced by 0; ``cancellations`` include look-ahead ones found
    again later; ``refreshes``: passes on which the matched filter ran after the onset decoder;
    ``undone``: detections reversed by a later one of the other sign. Energies are sums of
    squares in line units: a high residual to input ratio means missed events, a wrong bank, a
    gain error, noise or a lost byte. ``unresolved``: the overloaded energy in signatures plus
    the detections the residual test withheld (``rejected``). ``mean_amplitude`` (0 before the
    first detection) is the chip amplitude on the line, ``amplitude_in_use`` the one cancelled.
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
