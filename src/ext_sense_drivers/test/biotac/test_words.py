"""SPI reply words of the BioTac: value formula, odd parity, error replies."""

from __future__ import annotations

import numpy as np
import pytest

from ext_sense_drivers.biotac.errors import BioTacError
from ext_sense_drivers.biotac.words import (
    ODD_PARITY,
    WORD_STATUS,
    WORD_VALUE,
    ErrorReply,
    WordStatus,
    decode_word,
    encode_values,
)


def test_value_formula_and_parity():
    words = encode_values(np.arange(4096))
    b0, b1 = (words >> 8).astype(np.uint8), (words & 0xFF).astype(np.uint8)
    assert ODD_PARITY[b0].all()
    assert ODD_PARITY[b1].all()
    assert ((b1 >> 1) & 0b11 == 0).all()  # unused data bits of b1 stay 0
    assert ((b0 >> 1).astype(int) * 32 + (b1 >> 3)).tolist() == list(range(4096))
    assert WORD_VALUE[words].tolist() == list(range(4096))
    assert (WORD_STATUS[words] == WordStatus.OK).all()


def test_word_tables_agree_with_the_plain_decoding():
    for word in range(1 << 16):
        value, parity_failed, error = decode_word(word)
        status = WordStatus.ERROR_REPLY if error else WordStatus(int(parity_failed))
        assert (WORD_VALUE[word], WORD_STATUS[word]) == (value, status)


def test_known_words():
    # 4095: b0 = 0x7F << 1 | p (7 ones -> p = 0), b1 = 0x1F << 3 | p (5 ones -> p = 0)
    assert int(encode_values([4095])[0]) == 0xFEF8
    # 0: both bytes carry only the parity bit.
    assert int(encode_values([0])[0]) == 0x0101
    assert decode_word(0xFEF8) == (4095, False, False)
    assert decode_word(0xFEF9) == (0, True, False)


@pytest.mark.parametrize("reply", list(ErrorReply))
def test_error_replies_recognised_before_parity(reply):
    # Both error replies fail the parity check of b0; they must count as error replies.
    assert not ODD_PARITY[reply >> 8]
    assert decode_word(int(reply)) == (0, False, True)
    assert (WORD_VALUE[reply], WORD_STATUS[reply]) == (0, WordStatus.ERROR_REPLY)


@pytest.mark.parametrize("bad", [-1, 4096, 70000])
def test_encode_values_rejects_out_of_range(bad):
    with pytest.raises(BioTacError, match=r"must be in 0\.\.4095"):
        encode_values([0, bad])


def test_encode_values_rejects_floats():
    with pytest.raises(BioTacError, match="integers"):
        encode_values([1.5])
