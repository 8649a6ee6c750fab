"""Conversions between integer nanoseconds and ROS time fields.

Time inside ext_sense is always an ``int`` of nanoseconds: floats of seconds lose
sub-microsecond precision at epoch magnitudes, so they appear only at the edges. The unit
constants ``S``, ``MS`` and ``US`` (nanoseconds per unit) are defined here and nowhere else.
"""

from __future__ import annotations

S = 1_000_000_000
"""Nanoseconds in a second: ``2 * S`` is two seconds as integer nanoseconds."""
MS = 1_000_000
"""Nanoseconds in a millisecond."""
US = 1_000
"""Nanoseconds in a microsecond."""


def split_ns(ns: int) -> tuple[int, int]:
    """``builtin_interfaces`` ``(sec, nanosec)`` of integer ns (negative too), ``nanosec >= 0``."""
    return divmod(int(ns), S)


def join_ns(sec: int, nanosec: int) -> int:
    """Join ``builtin_interfaces`` ``(sec, nanosec)`` fields into integer nanoseconds."""
    return int(sec) * S + int(nanosec)


def stamp_to_ns(stamp: object) -> int:
    """Integer nanoseconds of any object with ``sec`` and ``nanosec`` attributes."""
    return join_ns(stamp.sec, stamp.nanosec)  # type: ignore[attr-defined]


def fill_stamp(stamp: object, ns: int) -> object:
    """Set ``sec``/``nanosec`` of a Time or Duration message in place and return it."""
    stamp.sec, stamp.nanosec = split_ns(ns)  # type: ignore[attr-defined]
    return stamp
