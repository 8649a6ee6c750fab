import argparse

import numpy as np
import pytest

from ext_sense_drivers.cli import CSV_HEADER, register
from ext_sense_drivers.nuskin.tact import decoded_path, read_tact
from ext_sense_drivers.nuskin.wire import encode_words


def _run(argv):
    parser = argparse.ArgumentParser()
    register(parser.add_subparsers(dest="command"))
    args = parser.parse_args(argv)
    return args.func(args)


def test_decode_writes_one_row_per_word_and_a_summary(tmp_path, capsys):
    raw = tmp_path / "cap_raw.tact"
    raw.write_bytes(b"\xe1" + encode_words([3, 80, 0], [7, 1023, 5], [1, 0, 0]))
    out = tmp_path / "events.csv"
    assert (
        _run(["nuskin", "decode", str(raw), "--out", str(out), "--flag-polarity", "is_positive"])
        == 0
    )
    lines = out.read_text().splitlines()
    assert CSV_HEADER == "word,polarity,taxel,value,flag"
    assert lines == [CSV_HEADER, "0,1,3,7,1", "1,-1,80,1023,0"]
    err = capsys.readouterr().err
    assert "words=2 resyncs=1 skipped_bytes=1 bad_taxel_words=1" in err


def test_decode_keeps_the_flag_bit_as_received_whatever_the_polarity_choice(tmp_path):
    raw = tmp_path / "cap_raw.tact"
    raw.write_bytes(encode_words([5, 6, 7], [100, 200, 300], [1, 0, 1]))
    out = tmp_path / "events.csv"
    assert _run(["nuskin", "decode", str(raw), "--out", str(out)]) == 0
    # default polarity 'ignore': polarity 0 for all, the wire bit still in its column
    assert out.read_text().splitlines()[1:] == ["0,0,5,100,1", "1,0,6,200,0", "2,0,7,300,1"]


def test_decode_missing_file_is_a_clear_error(tmp_path, capsys):
    assert _run(["nuskin", "decode", str(tmp_path / "nope"), "--out", str(tmp_path / "x")]) == 2
    assert "cannot read" in capsys.readouterr().err


@pytest.mark.real_data
def test_decode_real_capture_matches_the_lab_file(food_poking_dir, tmp_path, capsys):
    raw = food_poking_dir / "tofu_zero_3_raw.tact"
    out = tmp_path / "tofu.csv"
    assert _run(["nuskin", "decode", str(raw), "--out", str(out)]) == 0
    rows = np.loadtxt(out, delimiter=",", skiprows=1, dtype=np.int64, ndmin=2)
    tact = read_tact(decoded_path(raw))
    np.testing.assert_array_equal(rows[:, 0], np.arange(tact.taxel.shape[0]))
    np.testing.assert_array_equal(rows[:, 1], tact.flag)
    np.testing.assert_array_equal(rows[:, 2], tact.taxel)
    np.testing.assert_array_equal(rows[:, 3], tact.value)
    np.testing.assert_array_equal(rows[:, 4], tact.flag)  # the bit as received: the lab's col0
    assert f"words={tact.taxel.shape[0]} resyncs=0" in capsys.readouterr().err
