"""The NUSkin event CSV of ``ext-sense nuskin decode``: one row per word.

``flag`` is the word's flag bit as received, ``polarity`` its interpretation
(``--flag-polarity``), so the wire bit is never lost to a choice of meaning.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, TextIO

if TYPE_CHECKING:
    import numpy.typing as npt

CSV_HEADER = "word,polarity,taxel,value,flag"


def write_rows(
    out: TextIO,
    first_word: int,
    polarity: npt.ArrayLike,
    taxel: npt.ArrayLike,
    value: npt.ArrayLike,
    flag: npt.ArrayLike,
) -> int:
    """Append one CSV row per event (no header), words numbered from ``first_word``; return rows."""
    import numpy as np  # here: ``ext-sense --help`` imports this module for CSV_HEADER

    columns = [np.asarray(a, dtype=np.int64).ravel() for a in (polarity, taxel, value, flag)]
    n = columns[0].shape[0]
    if any(c.shape[0] != n for c in columns):
        raise ValueError(
            "The 'polarity', 'taxel', 'value' and 'flag' arrays must have one length. "
            f"Got {[c.shape[0] for c in columns]} instead."
        )
    if n:
        rows = np.column_stack((np.arange(first_word, first_word + n), *columns))
        np.savetxt(out, rows, fmt="%d", delimiter=",")
    return n
