"""Property tests of the bridge decoders: insertions, deletions, bit flips, any chunking.

Every frame left intact must come out exactly (values, holes, position), the vectorised decoder
must agree with the per-byte reference on frames and counters, and nothing may raise.
"""

from __future__ import annotations

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from ext_sense_drivers.biotac.decoder import BridgeDecoder
from ext_sense_drivers.biotac.encoder import encode_frame
from ext_sense_drivers.biotac.frames import BridgeFrames
from ext_sense_drivers.biotac.reference import ReferenceDecoder
from ext_sense_drivers.biotac.words import ErrorReply, encode_values

BAD_KINDS = ("parity", int(ErrorReply.PARITY_ERROR), int(ErrorReply.UNKNOWN_COMMAND))

frame_spec = st.fixed_dictionaries(
    {
        "sensor": st.integers(0, 4),
        "values": st.lists(st.integers(0, 4095), min_size=44, max_size=44),
        "bad": st.dictionaries(st.integers(0, 43), st.sampled_from(BAD_KINDS), max_size=3),
        "garbage": st.one_of(
            st.just(b""),
            st.binary(max_size=24),
            st.builds(lambda b: b"\xaa\x55" + b, st.binary(max_size=12)),
            st.just(b"\xaa"),
        ),
        "damage": st.one_of(
            st.none(),
            st.tuples(st.just("flip"), st.integers(0, 95), st.integers(0, 7)),
            st.tuples(st.just("delete"), st.integers(0, 95), st.integers(1, 5)),
            st.tuples(st.just("insert"), st.integers(2, 95), st.binary(min_size=1, max_size=5)),
        ),
    }
)


def build_stream(specs, first_seq):
    """The stream and, per generated frame, (offset or None when damaged, expected record)."""
    seq = list(first_seq)
    parts, expected, pos = [], [], 0
    for spec in specs:
        s = spec["sensor"]
        words = encode_values(np.array(spec["values"]))
        invalid = 0
        for k, kind in spec["bad"].items():
            words[k] = words[k] ^ 0x0100 if kind == "parity" else kind
            invalid |= 1 << k
        frame = encode_frame(seq[s], s, words)
        parts.append(spec["garbage"])
        pos += len(spec["garbage"])
        damage = spec["damage"]
        if damage is not None:
            kind, at, arg = damage
            b = bytearray(frame)
            if kind == "flip":
                b[at] ^= 1 << arg
            elif kind == "delete":
                del b[at : at + arg]
            else:
                b[at:at] = arg
            frame = bytes(b)
        values = [0 if invalid >> k & 1 else v for k, v in enumerate(spec["values"])]
        record = {
            "sensor_id": s,
            "seq": seq[s],
            "pac": tuple(values[0::2]),
            "electrodes": tuple(values[1:38:2]),
            "pdc": values[39],
            "tac": values[41],
            "tdc": values[43],
            "invalid_mask": invalid,
            "parity_errors": sum(1 for v in spec["bad"].values() if v == "parity"),
            "error_replies": sum(1 for v in spec["bad"].values() if v != "parity"),
        }
        expected.append((None if damage else pos, record))
        parts.append(frame)
        pos += len(frame)
        seq[s] = (seq[s] + 1) % 65536
    return b"".join(parts), expected


def run(decoder, stream, cuts):
    out, pos, i = [], 0, 0
    while pos < len(stream):
        step = cuts[i % len(cuts)] if cuts else len(stream)
        got = decoder.feed(stream[pos : pos + step])
        out += got.rows() if isinstance(got, BridgeFrames) else got
        pos += step
        i += 1
    got = decoder.flush()
    out += got.rows() if isinstance(got, BridgeFrames) else got
    return out


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    specs=st.lists(frame_spec, max_size=12),
    first_seq=st.lists(st.integers(0, 65535), min_size=5, max_size=5),
    cuts=st.lists(st.integers(1, 150), max_size=6),
    tail=st.binary(max_size=120),
)
def test_damaged_streams(specs, first_seq, cuts, tail):
    stream, expected = build_stream(specs, first_seq)
    stream += tail
    fast = BridgeDecoder()
    ref = ReferenceDecoder()
    got = run(fast, stream, cuts)
    got_ref = run(ref, stream, [7])
    assert got == got_ref
    assert fast.counters == ref.counters

    by_offset = {f.offset: f for f in got}
    intact = [(off, rec) for off, rec in expected if off is not None]
    for off, rec in intact:
        assert off in by_offset, f"intact frame at {off} lost"
        f = by_offset[off]
        assert {k: getattr(f, k) for k in rec} == rec

    c = fast.counters
    assert c.bytes_total == len(stream)
    if len(got) == len(intact):  # no chance frame made of garbage
        assert c.skipped_bytes == len(stream) - 96 * len(got)
        for s in range(5):
            flags = [off is not None for off, rec in expected if rec["sensor_id"] == s]
            if any(flags):
                first = flags.index(True)
                last = len(flags) - 1 - flags[::-1].index(True)
                assert c.dropped_frames[s] == flags[first:last].count(False)
            else:
                assert c.dropped_frames[s] == 0
            recs = [rec for off, rec in intact if rec["sensor_id"] == s]
            assert c.parity_errors[s] == sum(r["parity_errors"] for r in recs)
            assert c.error_replies[s] == sum(r["error_replies"] for r in recs)
            assert c.sensor_frames[s] == len(recs)


@settings(max_examples=200, deadline=None)
@given(stream=st.binary(max_size=600), cuts=st.lists(st.integers(1, 64), max_size=4))
def test_random_bytes_never_crash_and_agree(stream, cuts):
    fast, ref = BridgeDecoder(), ReferenceDecoder()
    assert run(fast, stream, cuts) == run(ref, stream, [])
    assert fast.counters == ref.counters
    assert fast.pending_bytes == 0


@settings(max_examples=100, deadline=None)
@given(
    specs=st.lists(frame_spec, min_size=1, max_size=6),
    cuts=st.lists(st.integers(1, 40), min_size=1, max_size=5),
)
def test_chunking_never_changes_the_result(specs, cuts):
    stream, _ = build_stream(specs, [0] * 5)
    whole = BridgeDecoder()
    pieces = BridgeDecoder()
    assert run(whole, stream, []) == run(pieces, stream, cuts)
    assert whole.counters == pieces.counters


def test_overlapping_valid_frames_take_the_first():
    # A valid frame whose payload holds another valid frame's bytes: the walk must keep the
    # outer one (the sequential reading never looks inside an accepted frame).
    inner = encode_frame(1, 0, [0x0101] * 2)  # 12 bytes, an "other" frame
    outer = encode_frame(2, 1, inner + b"\x01\x01" * ((88 - len(inner)) // 2))
    stream = inner[:0] + outer + encode_frame(3, 0, encode_values(np.zeros(44, int)))
    fast, ref = BridgeDecoder(), ReferenceDecoder()
    assert run(fast, stream, [5, 200]) == run(ref, stream, [])
    assert fast.counters == ref.counters
    assert fast.counters.other_frames == 0
