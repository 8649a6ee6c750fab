"""Hypothesis: bad bytes never crash the decoder; intact words always come through."""

import itertools

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from ext_sense_drivers.nuskin.reference import ReferenceDecoder
from ext_sense_drivers.nuskin.wire import WordDecoder, encode_words

words_st = st.lists(
    st.tuples(st.integers(1, 80), st.integers(0, 1023), st.integers(0, 1)),
    min_size=0,
    max_size=60,
)
# Damage inside one word: ("flip", byte, bit), ("delete", byte, _), ("insert", between, value).
damage_st = st.one_of(
    st.tuples(st.just("flip"), st.integers(0, 3), st.integers(0, 7)),
    st.tuples(st.just("delete"), st.integers(0, 3), st.just(0)),
    st.tuples(st.just("insert"), st.integers(1, 3), st.integers(0, 255)),
)
# Per word: junk bytes sent before it, and the damage done to it (none: it arrives intact).
word_fate_st = st.tuples(st.binary(max_size=6), st.lists(damage_st, max_size=2))


def _decode_chunked(raw, cuts):
    dec = WordDecoder()
    bounds = [0, *sorted(c % (len(raw) + 1) for c in cuts), len(raw)]
    out = []
    for a, b in itertools.pairwise(bounds):
        w = dec.feed(raw[a:b])
        out += list(zip(w.taxel.tolist(), w.value.tolist(), w.flag.tolist(), strict=True))
    return out, dec.counters


@settings(max_examples=300, deadline=None)
@given(st.binary(max_size=400), st.lists(st.integers(0, 10_000), max_size=10))
def test_arbitrary_bytes_never_crash_and_match_reference(raw, cuts):
    got, counters = _decode_chunked(raw, cuts)
    ref = ReferenceDecoder()
    assert got == ref.feed(raw)
    assert counters == ref.counters
    assert counters.words * 4 + counters.bad_taxel_words * 4 + counters.skipped_bytes <= len(raw)
    assert all(1 <= t <= 80 and 0 <= v <= 1023 for t, v, _ in got)


@settings(max_examples=300, deadline=None)
@given(words_st, st.lists(word_fate_st, max_size=60), st.lists(st.integers(), max_size=8))
def test_every_intact_word_is_recovered(words, fates, cuts):
    stream = bytearray()
    intact = []
    for k, (t, v, f) in enumerate(words):
        junk, damage = fates[k] if k < len(fates) else (b"", [])
        stream += junk
        word = bytearray(encode_words([t], [v], [f]))
        for kind, pos, arg in damage:
            pos = min(pos, len(word) - 1)
            if kind == "flip":
                word[pos] ^= 1 << arg
            elif kind == "delete":
                del word[pos]
            elif pos > 0:
                word.insert(pos, arg)
        if not damage:
            intact.append((t, v, f))
        stream += word
    got, counters = _decode_chunked(bytes(stream), cuts)
    # Intact words come out in order, as a subsequence of everything decoded.
    it = iter(got)
    for word in intact:
        assert any(g == word for g in it), word
    assert counters.words >= len(intact)


@settings(max_examples=200, deadline=None)
@given(words_st, st.lists(st.integers(), max_size=12), st.lists(st.integers(), max_size=12))
def test_chunking_never_changes_the_output(words, cuts_a, cuts_b):
    t = np.array([w[0] for w in words], dtype=np.int64)
    v = np.array([w[1] for w in words], dtype=np.int64)
    raw = b"\x07\xe1" + encode_words(t, v) + b"\x21\x44"
    assert _decode_chunked(raw, cuts_a) == _decode_chunked(raw, cuts_b)
