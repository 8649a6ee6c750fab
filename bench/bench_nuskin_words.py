"""NUSkin receiver-word decoding: vectorised WordDecoder vs the per-byte Python reference.

Prints words/s of the reference decoder, the vectorised one on one buffer, on 64 KiB, 4 KiB and
1 ms worst-case reads (80 taxels x 4 kHz), on a corrupted stream, and of the driver's whole word
path, each against the worst-case rate (target >= 10 M words/s). Then the arrival clock over a
pty: 320 words written every 1 ms, stamps against write times.

    python bench/bench_nuskin_words.py            # full (about 20 s)
    python bench/bench_nuskin_words.py --quick    # small version, a few seconds
"""

from __future__ import annotations

import argparse
import os
import threading
import time

import numpy as np

from ext_sense_drivers.nuskin.clock import ArrivalClock
from ext_sense_drivers.nuskin.reference import ReferenceDecoder
from ext_sense_drivers.nuskin.streams import WordStream
from ext_sense_drivers.nuskin.wire import WordDecoder, encode_words
from ext_sense_drivers.transports.base import Chunk
from ext_sense_drivers.transports.reader import StreamReader
from ext_sense_drivers.transports.serial_port import SerialTransport

WORST_CASE_WORDS_PER_S = 80 * 4000
TARGET_WORDS_PER_S = 10_000_000


def _best_of(fn, repeats):
    best = float("inf")
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t0)
    return best


def _vector(raw, chunk):
    def run():
        dec = WordDecoder()
        for i in range(0, len(raw), chunk):
            dec.feed(raw[i : i + chunk])
        return dec

    return run


def _reference(raw):
    def run():
        ReferenceDecoder().feed(raw)

    return run


def _driver_path(raw, chunk):
    def run():
        stream = WordStream(clock=ArrivalClock.for_baud(4_000_000))
        t = 0
        for i in range(0, len(raw), chunk):
            t += 1_000_000
            stream.feed(Chunk(raw[i : i + chunk], t))

    return run


def _clock_over_pty(seconds: float) -> None:
    """Stamp error of the arrival clock for words written to a pty at the worst-case rate."""
    words_per_ms = WORST_CASE_WORDS_PER_S // 1000
    n_writes = int(seconds * 1000)
    rng = np.random.default_rng(1)
    payload = encode_words(rng.integers(1, 81, words_per_ms), rng.integers(0, 1024, words_per_ms))
    master, slave = os.openpty()
    path = os.ttyname(slave)
    reader = StreamReader(SerialTransport(path, 4_000_000), read_timeout_s=0.02)
    reader.start()
    time.sleep(0.1)
    sent_ns = np.empty(n_writes, np.int64)

    def write() -> None:
        t_next = time.monotonic_ns()
        for k in range(n_writes):
            t_next += 1_000_000
            while time.monotonic_ns() < t_next:
                time.sleep(0.0002)
            sent_ns[k] = time.monotonic_ns()
            os.write(master, payload)

    writer = threading.Thread(target=write)
    writer.start()
    writer.join()
    time.sleep(0.1)
    reader.stop()
    os.close(master)
    os.close(slave)
    chunks = reader.drain()
    stream = WordStream(clock=ArrivalClock.for_baud(4_000_000))
    stamps = np.concatenate([stream.feed(c).t_ns for c in chunks])
    truth = np.repeat(sent_ns, words_per_ms)[: stamps.shape[0]]
    err_us = (stamps - truth) / 1e3
    gaps_us = np.diff([c.t_ns for c in chunks]) / 1e3
    print(
        f"arrival clock over a pty, {n_writes} writes of {words_per_ms} words every 1 ms: "
        f"{stamps.shape[0]:,} of {n_writes * words_per_ms:,} words, {len(chunks)} reads"
    )
    print(
        f"  read interval us: median {np.median(gaps_us):.0f}, "
        f"p99 {np.percentile(gaps_us, 99):.0f}, max {gaps_us.max():.0f}"
    )
    print(
        f"  stamp - write time us: median {np.median(err_us):.0f}, "
        f"p1 {np.percentile(err_us, 1):.0f}, p99 {np.percentile(err_us, 99):.0f}, "
        f"max |err| {np.abs(err_us).max():.0f}"
    )


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="small sizes, a few seconds")
    args = parser.parse_args()
    n_words = 400_000 if args.quick else 4_000_000
    n_ref = 20_000 if args.quick else 200_000
    repeats = 2 if args.quick else 3

    rng = np.random.default_rng(0)
    raw = encode_words(rng.integers(1, 81, n_words), rng.integers(0, 1024, n_words))
    bad = bytearray(raw)
    for i in rng.integers(0, len(bad), len(bad) // 10_000):
        bad[i] ^= 1 << int(rng.integers(0, 8))
    bad = bytes(bad)
    check = WordDecoder()
    check.feed(bad)
    per_ms = 4 * WORST_CASE_WORDS_PER_S // 1000

    rows = []
    t_ref = _best_of(_reference(raw[: 4 * n_ref]), repeats)
    rows.append(("reference per-byte Python, whole buffer", n_ref, t_ref))
    cases = [
        ("vectorised, whole buffer", raw, len(raw)),
        ("vectorised, 64 KiB chunks", raw, 1 << 16),
        ("vectorised, 4 KiB chunks", raw, 4096),
        (f"vectorised, 1 ms reads at worst case ({per_ms} B)", raw, per_ms),
        ("vectorised, corrupted 1e-4, 64 KiB chunks", bad, 1 << 16),
        ("vectorised, corrupted 1e-4, 1 ms reads", bad, per_ms),
    ]
    for name, data, chunk in cases:
        rows.append((name, n_words, _best_of(_vector(data, chunk), repeats)))
    rows.append(
        (
            "driver word path (decode + clock), 1 ms reads",
            n_words,
            _best_of(_driver_path(raw, per_ms), repeats),
        )
    )

    ref_rate = n_ref / t_ref
    print(f"NUSkin word decoding, {n_words:,} words ({len(raw) / 1e6:.1f} MB), best of {repeats}")
    print(
        f"worst case: 80 taxels x 4 kHz = {WORST_CASE_WORDS_PER_S:,} words/s; "
        f"target >= {TARGET_WORDS_PER_S / 1e6:.0f} M words/s"
    )
    print(
        f"corrupted stream: {check.counters.resyncs} resyncs, "
        f"{check.counters.skipped_bytes} bytes skipped"
    )
    print(f"{'case':<52}{'M words/s':>10}{'x ref':>9}{'x worst':>9}")
    for name, n, t in rows:
        rate = n / t
        print(
            f"{name:<52}{rate / 1e6:>10.2f}{rate / ref_rate:>9.1f}"
            f"{rate / WORST_CASE_WORDS_PER_S:>9.1f}"
        )
    big = rows[2][1] / rows[2][2]
    verdict = "meets" if big >= TARGET_WORDS_PER_S else "MISSES"
    print(f"64 KiB chunks: {big / 1e6:.1f} M words/s {verdict} the 10 M words/s target")
    _clock_over_pty(0.5 if args.quick else 3.0)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
