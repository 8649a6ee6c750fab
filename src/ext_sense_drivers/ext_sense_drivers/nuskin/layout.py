"""Where NUSkin taxels sit: ids 1..40 left finger, 41..80 right, row-major on an 8 x 5 lattice."""

from __future__ import annotations

from enum import IntEnum
from typing import NamedTuple

from ext_sense_drivers.nuskin.errors import NuskinError

N_TAXELS = 80
TAXELS_PER_FINGER = 40
ROWS = 8
COLUMNS = 5
FIRST_TAXEL = 1
LAST_TAXEL = 80


class Finger(IntEnum):
    """Which gripper finger carries a taxel."""

    LEFT = 0
    RIGHT = 1


class TaxelPlace(NamedTuple):
    """A taxel's finger and lattice cell."""

    finger: Finger
    row: int
    column: int


def place(taxel: int) -> TaxelPlace:
    """Finger, row and column of a taxel id 1..80."""
    if not FIRST_TAXEL <= int(taxel) <= LAST_TAXEL:
        raise NuskinError(f"The 'taxel' parameter must be in 1..80. Got {taxel} instead.")
    index = int(taxel) - 1
    cell = index % TAXELS_PER_FINGER
    return TaxelPlace(Finger(index // TAXELS_PER_FINGER), cell // COLUMNS, cell % COLUMNS)


def taxel_id(finger: Finger, row: int, column: int) -> int:
    """The taxel id at a finger's lattice cell, row 0..7, column 0..4 (inverse of :func:`place`)."""
    if not 0 <= row < ROWS:
        raise NuskinError(f"The 'row' parameter must be in 0..7. Got {row} instead.")
    if not 0 <= column < COLUMNS:
        raise NuskinError(f"The 'column' parameter must be in 0..4. Got {column} instead.")
    return int(Finger(finger)) * TAXELS_PER_FINGER + row * COLUMNS + column + 1
