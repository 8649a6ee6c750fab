import numpy as np
import pytest

from ext_sense_drivers.nuskin.errors import NuskinError
from ext_sense_drivers.nuskin.layout import Finger, place, taxel_id
from ext_sense_drivers.nuskin.reference import ReferenceDecoder
from ext_sense_drivers.nuskin.tact import decoded_path, read_tact, recorded_rate
from ext_sense_drivers.nuskin.wire import FlagPolarity, WordDecoder, encode_words


def _events(n, seed=0):
    rng = np.random.default_rng(seed)
    return rng.integers(1, 81, n), rng.integers(0, 1024, n), rng.integers(0, 2, n)


def test_round_trip_every_field():
    taxel, value, flag = _events(5000)
    out = WordDecoder(FlagPolarity.IS_POSITIVE).feed(encode_words(taxel, value, flag))
    np.testing.assert_array_equal(out.taxel, taxel)
    np.testing.assert_array_equal(out.value, value)
    np.testing.assert_array_equal(out.flag, flag)
    np.testing.assert_array_equal(out.polarity, np.where(flag == 1, 1, -1))
    np.testing.assert_array_equal(out.end, 4 * np.arange(1, 5001))


def test_field_extremes_and_documented_bit_layout():
    assert encode_words([1], [0]) == bytes([0x20, 0x42, 0x80, 0xE0])
    assert encode_words([80], [1023], [1]) == bytes([0x25, 0x41, 0x9F, 0xFF])
    out = WordDecoder().feed(bytes([0x25, 0x41, 0x9F, 0xFF]))
    assert (out.taxel.tolist(), out.value.tolist(), out.flag.tolist()) == ([80], [1023], [1])


def test_ignore_mode_gives_unknown_polarity():
    taxel, value, flag = _events(100)
    out = WordDecoder().feed(encode_words(taxel, value, flag))
    assert out.polarity.dtype == np.int8
    assert not out.polarity.any()


def test_out_of_range_taxels_counted_and_dropped():
    raw = encode_words([0, 5, 81, 127, 80], [1, 2, 3, 4, 5])
    dec = WordDecoder()
    out = dec.feed(raw)
    assert out.taxel.tolist() == [5, 80]
    assert out.value.tolist() == [2, 5]
    assert dec.counters.bad_taxel_words == 3
    assert dec.counters.words == 2
    assert dec.counters.resyncs == 0


def test_stream_starting_mid_word_is_one_resync():
    raw = encode_words([3, 4, 5], [10, 20, 30])
    dec = WordDecoder()
    out = dec.feed(raw[2:])
    assert out.taxel.tolist() == [4, 5]
    assert dec.counters.skipped_bytes == 2
    assert dec.counters.resyncs == 1


def test_garbage_run_split_across_chunks_is_one_resync():
    raw = encode_words([1], [1]) + bytes([0x00, 0xFF, 0x61, 0x13]) + encode_words([2], [2])
    dec = WordDecoder()
    words = [dec.feed(raw[i : i + 1]) for i in range(len(raw))]
    assert sum(w.size for w in words) == 2
    assert dec.counters.resyncs == 1
    assert dec.counters.skipped_bytes == 4


def test_held_back_prefix_and_flush():
    raw = encode_words([7], [9])
    dec = WordDecoder()
    assert dec.feed(raw[:3]).size == 0
    assert dec.pending == 3
    dec.flush()
    assert dec.pending == 0
    assert dec.counters.skipped_bytes == 3
    assert dec.counters.resyncs == 1


def test_empty_and_numpy_chunks():
    dec = WordDecoder()
    assert dec.feed(b"").size == 0
    arr = np.frombuffer(encode_words([9, 10], [1, 2]), np.uint8)
    assert dec.feed(arr).taxel.tolist() == [9, 10]


def test_agrees_with_reference_on_corrupted_stream():
    taxel, value, flag = _events(3000, seed=3)
    raw = bytearray(encode_words(taxel, value, flag))
    rng = np.random.default_rng(4)
    for i in rng.integers(0, len(raw), 200):
        raw[i] ^= 1 << int(rng.integers(0, 8))
    raw = bytes(raw[:500]) + bytes(rng.integers(0, 256, 77, dtype=np.uint8)) + bytes(raw[500:])
    ref = ReferenceDecoder()
    expect = ref.feed(raw)
    dec = WordDecoder()
    parts = [dec.feed(raw[i : i + 997]) for i in range(0, len(raw), 997)]
    got = [
        (t, v, f)
        for p in parts
        for t, v, f in zip(p.taxel.tolist(), p.value.tolist(), p.flag.tolist(), strict=True)
    ]
    assert got == expect
    assert dec.counters == ref.counters
    assert dec.counters.resyncs > 0


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"taxel": [1, 2], "value": [1]}, "one length"),
        ({"taxel": [128], "value": [1]}, "'taxel' values must be in 0..127. Got 128"),
        ({"taxel": [1], "value": [1024]}, "'value' values must be in 0..1023. Got 1024"),
        ({"taxel": [1], "value": [0], "flag": [2]}, "'flag' values must be in 0..1"),
    ],
)
def test_encode_rejects_bad_fields(kwargs, match):
    with pytest.raises(NuskinError, match=match):
        encode_words(**kwargs)


def test_layout_round_trip_and_fingers():
    for t in range(1, 81):
        p = place(t)
        assert taxel_id(p.finger, p.row, p.column) == t
    assert place(1) == (Finger.LEFT, 0, 0)
    assert place(40) == (Finger.LEFT, 7, 4)
    assert place(41) == (Finger.RIGHT, 0, 0)
    with pytest.raises(NuskinError, match=r"'taxel' parameter must be in 1\.\.80\. Got 81"):
        place(81)
    with pytest.raises(NuskinError, match="'row'"):
        taxel_id(Finger.LEFT, 8, 0)


def _raw_files(food_poking_dir):
    files = sorted(food_poking_dir.glob("*_raw.tact"))
    assert len(files) == 45
    return files


@pytest.mark.real_data
def test_real_captures_decode_to_the_lab_tact_word_for_word(food_poking_dir):
    exact = []
    for raw_path in _raw_files(food_poking_dir):
        dec = WordDecoder()
        out = dec.feed(raw_path.read_bytes())
        tact = read_tact(decoded_path(raw_path))
        n = tact.taxel.shape[0]
        assert out.size >= n, raw_path.name
        np.testing.assert_array_equal(out.taxel[:n], tact.taxel, err_msg=raw_path.name)
        np.testing.assert_array_equal(out.value[:n], tact.value, err_msg=raw_path.name)
        np.testing.assert_array_equal(out.flag[:n], tact.flag, err_msg=raw_path.name)
        assert dec.counters.resyncs == 0
        assert dec.counters.skipped_bytes == 0
        if out.size == n:
            exact.append(raw_path.name)
        else:
            assert raw_path.name == "watermelon_zero_9_raw.tact"
            assert out.size == n + 3
    assert len(exact) == 44


@pytest.mark.real_data
def test_real_capture_chunked_like_a_serial_port_matches_reference(food_poking_dir):
    raw = (food_poking_dir / "apple_zero_0_raw.tact").read_bytes()
    rng = np.random.default_rng(7)
    cuts = np.sort(rng.integers(0, len(raw), 300))
    dec = WordDecoder()
    taxels = []
    for a, b in zip(np.r_[0, cuts], np.r_[cuts, len(raw)], strict=True):
        taxels += dec.feed(raw[a:b]).taxel.tolist()
    assert taxels == [w[0] for w in ReferenceDecoder().feed(raw)]


@pytest.mark.real_data
def test_recorded_rate_from_markers(food_poking_dir):
    raw_path = food_poking_dir / "apple_zero_0_raw.tact"
    tact = read_tact(decoded_path(raw_path))
    rate = recorded_rate(raw_path)
    assert rate == pytest.approx(raw_path.stat().st_size / (tact.stop_s - tact.start_s))
    assert 100 < rate < 1e6


def test_tact_reader_errors(tmp_path):
    with pytest.raises(NuskinError, match="cannot read"):
        read_tact(tmp_path / "missing.tact")
    bad = tmp_path / "x.tact"
    bad.write_text("0 1 2 3.0\n0 1 2 3.0\n")
    with pytest.raises(NuskinError, match="must start with '1 1 1 t'"):
        read_tact(bad)
    with pytest.raises(NuskinError, match=r"must end in '_raw\.tact'"):
        decoded_path(tmp_path / "x.tact")


def test_words_round_trip_through_the_drivers_decoder():
    from ext_sense_drivers.nuskin.wire import WordDecoder, encode_words

    taxel = np.array([1, 40, 41, 80], dtype=np.uint16)
    value = np.array([0, 5, 512, 1023], dtype=np.uint16)
    got = WordDecoder().feed(encode_words(taxel, value))
    np.testing.assert_array_equal(got.taxel, taxel)
    np.testing.assert_array_equal(got.value, value)
