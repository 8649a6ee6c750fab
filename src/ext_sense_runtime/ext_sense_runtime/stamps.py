"""Conversions between integer nanoseconds and ROS time fields.

Time inside ext_sense is always an ``int`` of nanoseconds (epoch or monotonic, as stated where
it is used); floats of seconds lose sub-microsecond precision at epoch magnitudes, so they only
appear at the edges (printing, plotting). The unit constants ``S``, ``MS`` and ``US`` (nanoseconds
per unit) are defined here and nowhere else.
"""

from __future__ import annotations

S = 1_000_000_000
"""Nanoseconds in a second: ``2 * S`` is two seconds as integer nanoseconds."""
MS = 1_000_000
"""Nanoseconds in a millisecond."""
US = 1_000
"""Nanoseconds in a microsecond."""
NS_PER_S = S


def split_ns(ns: int) -> tuple[int, int]:
    """Split integer nanoseconds into ``(sec, nanosec)`` with ``0 <= nanosec < 1e9``.

    Args:
        ns: Time or duration in nanoseconds (may be negative).

    Returns:
        The ``sec`` and ``nanosec`` fields of ``builtin_interfaces`` Time or Duration.
    """
    sec, nanosec = divmod(int(ns), NS_PER_S)
    return sec, nanosec


def join_ns(sec: int, nanosec: int) -> int:
    """Join ``builtin_interfaces`` ``(sec, nanosec)`` fields into integer nanoseconds."""
    return int(sec) * NS_PER_S + int(nanosec)


def stamp_to_ns(stamp: object) -> int:
    """Integer nanoseconds of any object with ``sec`` and ``nanosec`` attributes."""
    return join_ns(stamp.sec, stamp.nanosec)  # type: ignore[attr-defined]


def fill_stamp(stamp: object, ns: int) -> object:
    """Set ``sec``/``nanosec`` of a Time or Duration message in place and return it."""
    stamp.sec, stamp.nanosec = split_ns(ns)  # type: ignore[attr-defined]
    return stamp
