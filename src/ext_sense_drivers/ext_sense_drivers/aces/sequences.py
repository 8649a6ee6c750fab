"""Binary code families for the ACES signature bank: m-sequences and Gold families.

No randomness: a family follows from its LFSR polynomials alone.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from ext_sense_drivers.aces.errors import AcesError


def m_sequence(poly: int, degree: int) -> npt.NDArray[np.uint8]:
    """One period ``(2**degree - 1,)`` uint8 of the m-sequence of a primitive polynomial.

    ``poly`` is a bit mask (``0b10001001`` for ``x^7 + x^3 + 1``); the recurrence
    ``a[k + degree] = XOR of a[k + i]`` over its bits ``i < degree`` starts from all ones.
    AcesError if the mask is not of that degree with a constant term, or not primitive.
    """
    if degree < 2 or poly >> degree != 1 or not poly & 1:
        raise AcesError(
            f"The 'poly' parameter must be a degree-{degree} mask with bits 0 and {degree} set. "
            f"Got {poly:#b} instead."
        )
    period = (1 << degree) - 1
    taps = [i for i in range(degree) if poly >> i & 1]
    bits = np.ones(period + degree, np.uint8)
    for k in range(period):
        acc = 0
        for i in taps:
            acc ^= int(bits[k + i])
        bits[k + degree] = acc
    seq = bits[:period]
    if (
        not np.array_equal(bits[period : period + degree], seq[:degree])
        or seq.sum() != (period + 1) // 2
    ):
        raise AcesError(f"The polynomial {poly:#b} is not primitive: its sequence is not maximal.")
    return seq


def gold_family(poly_u: int, poly_v: int, degree: int) -> npt.NDArray[np.uint8]:
    """The Gold family of a preferred pair of polynomials: ``(2**degree + 1, 2**degree - 1)`` bits.

    Rows ``u``, ``v``, then ``u XOR roll(v, -k)`` for every ``k`` (AcesError if not primitive).
    """
    u = m_sequence(poly_u, degree)
    v = m_sequence(poly_v, degree)
    period = u.shape[0]
    shifts = (np.arange(period)[:, None] + np.arange(period)[None, :]) % period
    family = np.empty((period + 2, period), np.uint8)
    family[0] = u
    family[1] = v
    family[2:] = u[None, :] ^ v[shifts]
    return family


def to_chips(bits: npt.NDArray[np.uint8]) -> npt.NDArray[np.int8]:
    """Map bits to antipodal chips: 0 -> +1, 1 -> -1 (the usual BPSK mapping)."""
    return (1 - 2 * bits.astype(np.int8)).astype(np.int8)
