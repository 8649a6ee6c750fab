"""Recordings survive a crash: a bag cut off at any point, or written by a process killed with
SIGKILL or stopped by a full disk, gives back every message flushed before (salvage, recover).
"""

import itertools
import os
import shutil
import signal
import struct
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest
from ext_sense_bags.recover import bag_problem
from rosbags.rosbag2 import Reader

from ext_sense_bags import (
    BagError,
    BagReader,
    BagWriter,
    Storage,
    ground_truth,
    recover_bag,
    taxel_event_batch,
    type_hash,
)

T0 = 1_700_000_000_000_000_000
EVENTS = "/extsense/nuskin/events"
TRUTH = "/extsense/ground_truth"
STEP_NS = 1_000_000
NEVER = 1e9  # a flush period no test reaches: only explicit flushes


def _write_one(bag: BagWriter, i: int) -> None:
    """Message ``i``: an event batch at T0 + i ms (its value says i), every 7th a ground truth."""
    t = T0 + i * STEP_NS
    if i % 7 == 3:
        bag.write(TRUTH, t, ground_truth(t, "tap_localization", i, tap_position_m=0.01))
    else:
        n = 1 + i % 30
        batch = taxel_event_batch(t, np.arange(1, n + 1), np.ones(n), np.full(n, i), np.arange(n))
        bag.write(EVENTS, t, batch)


def _expected_topics(n: int) -> dict[str, int]:
    truths = sum(1 for i in range(n) if i % 7 == 3)
    return {k: v for k, v in {EVENTS: n - truths, TRUTH: truths}.items() if v}


def _check_prefix(bag_dir: Path, n: int) -> None:
    """The bag holds exactly messages 0..n-1, in order, readable by plain rosbags."""
    with BagReader(bag_dir) as bag:
        assert bag.salvaged == ""
        times = [r.log_time_ns for r in bag.records()]
        assert times == [T0 + i * STEP_NS for i in range(n)]
        for rec, msg in bag.messages([EVENTS]) if EVENTS in bag.topics else []:
            i = (rec.log_time_ns - T0) // STEP_NS
            assert msg.value.tolist() == [i] * (1 + i % 30)
        assert {t: s.count for t, s in bag.topics.items() if s.count} == _expected_topics(n)
    with Reader(bag_dir) as reader:  # the metadata.yaml of a complete bag
        assert reader.message_count == n
        for conn in reader.connections:
            assert conn.digest == type_hash(conn.msgtype)


def _mcap_with_flush_points(tmp_path: Path, n: int = 90, every: int = 10):
    """Write ``n`` messages, flushing after every ``every``; then 5 more that stay pending.

    Returns:
        The file's bytes as a crash would leave them, and ``[(size, flushed)]`` after each flush.
    """
    bag = BagWriter(tmp_path / "src", flush_period_s=NEVER).open()
    points = [((tmp_path / "src" / "src.mcap").stat().st_size, 0)]
    for i in range(n):
        _write_one(bag, i)
        if i % every == every - 1:
            bag.flush()
            points.append(((tmp_path / "src" / "src.mcap").stat().st_size, bag.flushed))
    for i in range(n, n + 5):
        _write_one(bag, i)  # pending in memory: lost in a crash
    image = (tmp_path / "src" / "src.mcap").read_bytes()
    bag.close()
    return image, points


def test_mcap_cut_anywhere_gives_back_every_flushed_message(tmp_path):
    image, points = _mcap_with_flush_points(tmp_path)
    assert len(image) == points[-1][0]  # the pending messages never reached the file
    header_end = points[0][0]
    cuts: dict[int, int] = {0: 0, 5: 0, header_end: 0}  # cut -> messages expected back
    for (size, flushed), (next_size, _) in itertools.pairwise(points):
        (length,) = struct.unpack_from("<Q", image, size + 1)
        chunk_end = size + 9 + length  # the next chunk record; its message indexes follow
        assert chunk_end < next_size
        for cut in (size + 1, size + 20, chunk_end - 1):
            cuts[cut] = flushed
        if flushed:
            cuts[size - 1] = flushed  # only the last message index is cut: the chunk is whole
            cuts[size] = flushed
    cuts[len(image)] = points[-1][1]
    for cut, expected in sorted(cuts.items()):
        bag_dir = tmp_path / f"cut{cut}"
        bag_dir.mkdir()
        (bag_dir / "cut.mcap").write_bytes(image[:cut])
        if expected == 0 and cut > header_end:  # only a cut-off first chunk: nothing to read
            with pytest.raises(BagError, match=rf"cut\.mcap has no footer.*byte {header_end}"):
                BagReader(bag_dir).open()
            continue
        with BagReader(bag_dir) as bag:  # readable without recovery
            assert bag.message_count == expected, cut
            assert len(list(bag.records())) == expected
            assert "no footer" in bag.salvaged or "empty" in bag.salvaged
        result = recover_bag(bag_dir)
        assert result.messages == expected, cut
        assert result.kept == tmp_path / f"cut{cut}.damaged"
        last_flush = max(s for s, f in points if f == expected)
        if cut >= header_end:
            assert result.report.bytes_dropped == cut - last_flush or (
                expected and cut == last_flush - 1  # the cut index is not counted as lost
            )
        _check_prefix(bag_dir, expected)
        assert (tmp_path / f"cut{cut}.damaged" / "cut.mcap").read_bytes() == image[:cut]


def test_mcap_spoiled_chunk_is_dropped_and_the_rest_kept(tmp_path):
    image, points = _mcap_with_flush_points(tmp_path)
    spoiled = bytearray(image)
    (size, _), (_, flushed_after) = points[3], points[4]
    spoiled[size + 200] ^= 0xFF  # inside the 4th chunk's records: its CRC no longer matches
    (tmp_path / "bag").mkdir()
    (tmp_path / "bag" / "bag.mcap").write_bytes(bytes(spoiled))
    result = recover_bag(tmp_path / "bag", tmp_path / "out")
    assert result.report.chunks_dropped == 1
    assert "checksum mismatch" in result.report.problem
    assert result.messages == points[-1][1] - (flushed_after - points[3][1])
    with BagReader(tmp_path / "out") as bag:
        times = [r.log_time_ns for r in bag.records()]
    lost = {T0 + i * STEP_NS for i in range(points[3][1], flushed_after)}
    assert times == [T0 + i * STEP_NS for i in range(points[-1][1]) if T0 + i * STEP_NS not in lost]


def test_sqlite3_crash_images_give_back_every_committed_message(tmp_path):
    bag = BagWriter(tmp_path / "src", storage=Storage.SQLITE3, flush_period_s=NEVER).open()
    images: list[tuple[Path, int]] = []
    for i in range(60):
        _write_one(bag, i)
        if i % 10 == 9:
            bag.flush()
        if i % 10 in (9, 4):  # after a commit, and with 5 messages not committed
            image = tmp_path / f"image{i}"
            shutil.copytree(tmp_path / "src", image)
            images.append((image, bag.flushed))
    bag.close()
    assert not list((tmp_path / "src").glob("*.db3-*"))  # closed: one self-contained file
    for image, expected in images:
        assert bag_problem(image)  # no metadata.yaml, the write-ahead log still there
        result = recover_bag(image)
        assert result.messages == expected
        assert result.report.storage == "sqlite3"
        _check_prefix(image, expected)


CHILD = textwrap.dedent(
    """
    import resource, sys
    sys.path[:0] = [{test_dir!r}]
    from test_recover import _write_one
    from ext_sense_bags import BagError, BagWriter
    if {fsize_limit}:
        resource.setrlimit(resource.RLIMIT_FSIZE, ({fsize_limit}, {fsize_limit}))
    bag = BagWriter({path!r}, storage={storage!r}, flush_period_s=0.02).open()
    reported, i = 0, 0
    try:
        while True:
            _write_one(bag, i)
            i += 1
            if bag.flushed != reported:
                reported = bag.flushed
                print("flushed", reported, flush=True)
    except BagError as err:
        print("error", err, flush=True)
        print("flushed", bag.flushed, flush=True)
    """
)


def _child(tmp_path: Path, storage: str, fsize_limit: int = 0) -> subprocess.Popen:
    code = CHILD.format(
        test_dir=str(Path(__file__).parent),
        fsize_limit=fsize_limit,
        path=str(tmp_path / "bag"),
        storage=storage,
    )
    return subprocess.Popen(
        [sys.executable, "-c", code], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True
    )


@pytest.mark.parametrize("storage", ["mcap", "sqlite3"])
@pytest.mark.parametrize("kill_after", [1, 6])
def test_writer_killed_with_sigkill_loses_only_what_was_not_flushed(tmp_path, storage, kill_after):
    proc = _child(tmp_path, storage)
    flushed = 0
    try:
        for line in proc.stdout:
            flushed = int(line.split()[1])
            kill_after -= 1
            if kill_after == 0:
                os.kill(proc.pid, signal.SIGKILL)  # mid-write: it keeps writing until now
                break
    finally:
        proc.kill()
        _, err = proc.communicate()
    assert proc.returncode == -signal.SIGKILL, err
    assert flushed > 0
    result = recover_bag(tmp_path / "bag")
    print(f"{storage}: {flushed} flushed before SIGKILL, {result.messages} recovered")
    assert result.messages >= flushed
    _check_prefix(tmp_path / "bag", result.messages)


@pytest.mark.parametrize("storage", ["mcap", "sqlite3"])
def test_full_disk_stops_the_writer_with_a_clear_error(tmp_path, storage):
    proc = _child(tmp_path, storage, fsize_limit=300_000)  # files over 300 kB: EFBIG
    out, err = proc.communicate(timeout=60)
    assert proc.returncode == 0, err
    lines = out.splitlines()
    assert lines[-2].startswith("error Cannot write bag"), lines[-3:]
    assert "recording stopped after" in lines[-2]
    assert f"ext-sense bag recover {tmp_path / 'bag'}" in lines[-2]
    assert "Errno 27" in lines[-2] or "full" in lines[-2]  # EFBIG, or SQLite's "disk is full"
    flushed = int(lines[-1].split()[1])
    assert flushed > 0
    result = recover_bag(tmp_path / "bag")
    assert result.messages >= flushed
    _check_prefix(tmp_path / "bag", result.messages)


def test_writer_errors_are_bag_errors(tmp_path):
    (tmp_path / "file").write_text("x")
    with pytest.raises(BagError, match=r"Cannot create bag .*Not a directory"):
        BagWriter(tmp_path / "file" / "bag").open()
    with pytest.raises(BagError, match="flush_period_s"):
        BagWriter(tmp_path / "b", flush_period_s=0)
    with BagWriter(tmp_path / "b") as bag, pytest.raises(BagError, match=">= 0 ns"):
        bag.write_raw(EVENTS, -1, b"\x00\x01\x00\x00")
    with BagWriter(tmp_path / "c", flush_period_s=1e-9) as bag:  # due at every write
        for i in range(3):
            _write_one(bag, i)
            assert bag.flushed == i + 1
        assert not bag.flush_if_due()  # nothing pending


def test_recover_refuses_what_cannot_be_read_and_leaves_whole_bags_alone(tmp_path):
    with BagWriter(tmp_path / "whole") as bag:
        _write_one(bag, 0)
    assert bag_problem(tmp_path / "whole") == ""
    (tmp_path / "junk").mkdir()
    (tmp_path / "junk" / "junk.mcap").write_bytes(b"not an mcap file at all")
    with pytest.raises(BagError, match=r"junk\.mcap is not an mcap file"):
        recover_bag(tmp_path / "junk")
    (tmp_path / "empty").mkdir()
    with pytest.raises(BagError, match=r"empty holds no \.mcap or \.db3"):
        recover_bag(tmp_path / "empty")
    with pytest.raises(BagError, match="does not exist"):
        recover_bag(tmp_path / "nope")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["empty", "junk", "whole"]


@pytest.mark.parametrize("storage", ["mcap", "sqlite3"])
def test_crashed_bag_reads_in_log_time_order_and_recovers_in_recorded_order(tmp_path, storage):
    order = [5, 6, 7, 0, 1, 2, 9, 3, 4, 8]  # arrival order: log times out of order across flushes
    bag = BagWriter(tmp_path / "src", storage=storage, flush_period_s=NEVER).open()
    for k, i in enumerate(order):
        _write_one(bag, i)
        if k % 3 == 2:
            bag.flush()
    bag.flush()
    shutil.copytree(tmp_path / "src", tmp_path / "crashed")
    bag.close()
    with BagReader(tmp_path / "crashed") as crashed:
        assert crashed.salvaged
        assert [(r.log_time_ns - T0) // STEP_NS for r in crashed.records()] == list(range(10))
        assert crashed.start_time_ns == T0
        assert crashed.duration_ns == 9 * STEP_NS + 1
        assert [(r.log_time_ns - T0) // STEP_NS for r in crashed.records([TRUTH])] == [3]
        with pytest.raises(BagError, match="not in bag"):
            list(crashed.records(["/nope"]))
    recover_bag(tmp_path / "crashed", tmp_path / "out")
    with Reader(tmp_path / "out") as reader:  # rewritten as recorded: arrival order in the file
        stored = [t for _, t, _ in reader.messages()]
    assert sorted(stored) == [T0 + i * STEP_NS for i in range(10)]


ONE_FLUSH = textwrap.dedent(
    """
    import resource, sys
    sys.path[:0] = [{test_dir!r}]
    from test_recover import _write_one
    from ext_sense_bags import BagError, BagWriter
    if {fsize_limit}:
        resource.setrlimit(resource.RLIMIT_FSIZE, ({fsize_limit}, {fsize_limit}))
    bag = BagWriter({path!r}, storage="mcap", flush_period_s=3600.0).open()
    for i in range(20):
        _write_one(bag, i)
    try:
        bag.flush()
    except BagError as err:
        print("error", err, flush=True)
    print("flushed", bag.flushed, flush=True)
    """
)


def test_a_flush_cut_in_its_indexes_counts_the_whole_chunk_the_recovery_finds(tmp_path):
    """A full disk that cuts a flush after its chunk record, in the message indexes: the
    writer says the chunk's messages are flushed, as many as ``bag recover`` gives back (it
    said none, while the recovery found them: 245 of 832 in a live graph's recorder)."""

    def run(where: Path, limit: int) -> list[str]:
        code = ONE_FLUSH.format(
            test_dir=str(Path(__file__).parent), fsize_limit=limit, path=str(where)
        )
        out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
        assert out.returncode == 0, out.stderr
        return out.stdout.splitlines()

    assert run(tmp_path / "free", 0) == ["flushed 20"]
    chunk_end = _first_chunk_end((tmp_path / "free" / "free.mcap").read_bytes())
    cut = run(tmp_path / "cut", chunk_end + 5)  # the chunk whole, its first index cut
    assert cut[0].startswith("error Cannot write bag"), cut
    assert "20 of them flushed" in cut[0], cut
    assert cut[-1] == "flushed 20"
    assert recover_bag(tmp_path / "cut").messages == 20
    short = run(tmp_path / "short", chunk_end - 5)  # the chunk itself cut: none of it
    assert "0 of them flushed" in short[0], short
    with pytest.raises(BagError, match="nothing to read"):
        recover_bag(tmp_path / "short")


def _first_chunk_end(data: bytes) -> int:
    """File offset just after the first chunk record (opcode 0x06) of an mcap file."""
    at = 8  # the magic
    while data[at] != 0x06:
        at += 9 + int.from_bytes(data[at + 1 : at + 9], "little")  # opcode, length, body
    return at + 9 + int.from_bytes(data[at + 1 : at + 9], "little")
