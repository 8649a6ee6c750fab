"""``ext-sense biotac decode|encode`` and the JSON-lines form."""

from __future__ import annotations

import argparse
import json
import re

import numpy as np
import pytest

from ext_sense_drivers.biotac.cli import register_biotac
from ext_sense_drivers.biotac.decoder import BridgeDecoder
from ext_sense_drivers.biotac.encoder import encode_frame
from ext_sense_drivers.biotac.errors import BioTacError
from ext_sense_drivers.biotac.jsonl import KEYS, frames_to_records, record_to_frame
from ext_sense_drivers.biotac.words import ErrorReply, encode_values


def cli(argv):
    parser = argparse.ArgumentParser(prog="ext-sense")
    register_biotac(parser.add_subparsers(dest="command"))
    args = parser.parse_args(argv)
    return args.func(args)


def record(sensor, seq=None, base=0):
    r = {
        "sensor_id": sensor,
        "pac": [(base + i * 37) % 4096 for i in range(22)],
        "electrodes": [(base + 1000 + i) % 4096 for i in range(19)],
        "pdc": 2000,
        "tac": 2100,
        "tdc": 2200,
        "parity_errors": 0,
    }
    if seq is not None:
        r["seq"] = seq
    return r


def test_encode_then_decode_round_trip(tmp_path, capsys):
    records = [record(s, base=17 * k) for k in range(6) for s in (0, 3)]
    records[3]["pac"][5] = None
    records[3]["tdc"] = None
    values = tmp_path / "in.jsonl"
    values.write_text("".join(json.dumps(r) + "\n" for r in records))
    stream = tmp_path / "stream.bin"
    assert cli(["biotac", "encode", str(values), "--out", str(stream)]) == 0
    assert stream.stat().st_size == 96 * len(records)
    out = tmp_path / "frames.jsonl"
    assert cli(["biotac", "decode", str(stream), "--out", str(out)]) == 0
    err = capsys.readouterr().err
    assert "frames=12" in err
    assert "parity_errors=2" in err
    got = [json.loads(line) for line in out.read_text().splitlines()]
    assert [tuple(g) for g in got] == [KEYS] * len(records)
    expected_seq = [k for k in range(6) for _ in (0, 3)]
    assert [g["seq"] for g in got] == expected_seq
    for g, r in zip(got, records, strict=True):
        for key in ("sensor_id", "pac", "electrodes", "pdc", "tac", "tdc"):
            assert g[key] == r[key]
    assert got[3]["parity_errors"] == 2
    assert got[3]["pac"][5] is None


def test_decode_skips_garbage_and_reports_counters(tmp_path, capsys):
    good = encode_frame(7, 1, encode_values(np.full(44, 100)))
    bad = bytearray(good)
    bad[40] ^= 0x10
    stream = tmp_path / "s.bin"
    stream.write_bytes(b"junk" + bytes(bad) + good + good[:30])
    out = tmp_path / "f.jsonl"
    assert cli(["biotac", "decode", str(stream), "--out", str(out)]) == 0
    lines = out.read_text().splitlines()
    assert len(lines) == 1
    assert json.loads(lines[0])["seq"] == 7
    summary = capsys.readouterr().err.strip().splitlines()
    assert len(summary) == 1
    assert "crc_failures=1" in summary[0]
    assert "truncated=1" in summary[0]


def test_error_replies_come_out_null():
    words = encode_values(np.arange(44))
    words[1] = ErrorReply.UNKNOWN_COMMAND
    (rec,) = frames_to_records(BridgeDecoder().feed(encode_frame(0, 0, words)))
    assert rec["electrodes"][0] is None
    assert rec["parity_errors"] == 0


def test_decode_missing_file(tmp_path, capsys):
    assert cli(["biotac", "decode", str(tmp_path / "nope.bin")]) == 2
    assert "cannot read" in capsys.readouterr().err


def test_encode_bad_line(tmp_path, capsys):
    values = tmp_path / "in.jsonl"
    values.write_text(json.dumps(record(0)) + "\n" + "{not json\n")
    assert cli(["biotac", "encode", str(values), "--out", str(tmp_path / "o.bin")]) == 2
    assert f"{values}, line 2: not JSON" in capsys.readouterr().err
    assert not (tmp_path / "o.bin").exists()  # no half-written stream


GOOD = json.dumps(record(0)).encode()


def _with(**change):
    return json.dumps(record(0) | change).encode()


def _without(key):
    r = record(0)
    del r[key]
    return json.dumps(r).encode()


@pytest.mark.parametrize(
    ("line", "match"),
    [
        (b'{"sensor_id": 0, "pac": "\xff\xfe"}', r"not UTF-8 \(byte b'\\xff' at column 26\)"),
        (b"\xef\xbb\xbf" + GOOD, "not JSON: Unexpected UTF-8 BOM"),
        (b"{not json", "not JSON: Expecting property name enclosed in double quotes"),
        (GOOD[:-1], "not JSON: Expecting ',' delimiter"),
        (b"[" * 100_000 + b"]" * 100_000, "nested too deeply"),
        (b'{"pac": ' + b"[" * 100_000 + b"]" * 100_000 + b"}", "nested too deeply"),
        (b'{"seq": ' + b"9" * 5000 + b"}", "unreadable JSON: Exceeds the limit"),
        (b"[1, 2]", "expected a JSON object. Got list"),
        (b'"text"', "expected a JSON object. Got str"),
        (_without("sensor_id"), "the key 'sensor_id' is missing"),
        (_without("pac"), "the key 'pac' is missing"),
        (_without("tdc"), "the key 'tdc' is missing"),
        (_with(sensor_id="0"), "'sensor_id' must be an integer in 0..4. Got '0'"),
        (_with(sensor_id=True), "'sensor_id' must be an integer"),
        (_with(seq=1.5), "'seq' must be an integer in 0..65535. Got 1.5"),
        (_with(pac={"a": 1}), "'pac' must be a list of 22 values. Got dict"),
        (_with(pac=[0] * 23), "'pac' must be a list of 22 values. Got 23 values"),
        (_with(electrodes=[[0]] * 19), r"'electrodes' values must be integers .* Got \[0\]"),
        (_with(pdc="x" * 500), r"'pdc' values .* Got 'xxxxx.*\.\.\. instead"),
        (_with(tac=-1), "'tac' values must be integers in 0..4095 or null. Got -1"),
        (GOOD.replace(b'"pdc": 2000', b'"pdc": NaN'), "'pdc' values .* Got nan"),
        (GOOD.replace(b'"pdc": 2000', b'"pdc": 1e999'), "'pdc' values .* Got inf"),
    ],
)
def test_encode_malformed_input_is_one_line_with_the_line_number(tmp_path, capsys, line, match):
    values = tmp_path / "in.jsonl"
    values.write_bytes(GOOD + b"\n\n" + line + b"\n" + GOOD + b"\n")
    out = tmp_path / "o.bin"
    assert cli(["biotac", "encode", str(values), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1, err
    assert err.startswith(f"ext-sense biotac encode: {values}, line 3: ")
    assert re.search(match, err), err
    assert len(err) < 300
    assert not out.exists()


def test_encode_reads_stdin_and_names_it(monkeypatch, tmp_path, capsys):
    import io

    stdin = io.TextIOWrapper(io.BytesIO(GOOD + b"\n" + b"\x80\n"))
    monkeypatch.setattr("sys.stdin", stdin)
    assert cli(["biotac", "encode", "-", "--out", str(tmp_path / "o.bin")]) == 2
    assert "<stdin>, line 2: not UTF-8" in capsys.readouterr().err


@pytest.mark.parametrize(
    ("change", "match"),
    [
        ({"sensor_id": 5}, "'sensor_id'"),
        ({"seq": 70000}, "'seq'"),
        ({"pac": [0] * 21}, "'pac' must be a list of 22"),
        ({"pdc": 4096}, "'pdc' values"),
        ({"electrodes": [1.5] * 19}, "'electrodes' values"),
    ],
)
def test_record_validation(change, match):
    with pytest.raises(BioTacError, match=match):
        record_to_frame(record(0) | change)


def test_record_missing_key():
    r = record(0)
    del r["tac"]
    with pytest.raises(BioTacError, match="'tac' is missing"):
        record_to_frame(r)
