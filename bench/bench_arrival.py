"""The NUSkin arrival clock under load: stamp error of the real reader, quiet and with a CPU hog.

The reader stamps each read when it returns, so a late reader stamps a whole chunk at once
(issue #16). An emitter process plays a stream on a pty at the simulator's word times; this
process reads it with the driver's ``StreamReader`` and ``WordStream``, drained every 1 ms, and
compares each stamp with its due time. Streams ``4k`` (80 taxels x 4 kHz) and ``taps``, quiet
and ``hog``, each with the scheduling ``default``, ``reader`` (the reader at SCHED_FIFO 50) and
``best`` (``reader_priority`` 50 as the driver takes it: drainer at 40 too). Printed per run:
read intervals, stamp error, words in the wrong 1 ms bin (after the median offset), reads more
than 2 ms late, and the emitter's own lag.

    python bench/bench_arrival.py              # 8 s per run, both streams (about 3 min)
    python bench/bench_arrival.py --quick      # 2 s per run (about 1 min)
    python bench/bench_arrival.py --json f.json  # also the read-delay quantiles (augmentation)
"""

from __future__ import annotations

import argparse
import contextlib
import json
import multiprocessing as mp
import os
import sys
import time
import tty
from pathlib import Path
from typing import NamedTuple

import numpy as np
from common import start_hog, stop_hog

from ext_sense_drivers.nuskin.driver_config import DriverConfig
from ext_sense_drivers.nuskin.wire import encode_words
from ext_sense_drivers.transports.reader import StreamReader
from ext_sense_drivers.transports.scheduling import raise_thread_priority
from ext_sense_drivers.transports.serial_port import SerialTransport

BAUD = 4_000_000
"""The graphs' NUSkin link rate (sets the arrival clock's spread cap)."""
BEST_PRIORITY = 50
EMITTER_PRIORITY = 60
EMIT_PERIOD_S = 0.00025
"""The emitter writes what is due every 0.25 ms (a USB receiver delivers in 0.125-1 ms frames)."""
DRAIN_PERIOD_S = 0.001
"""The driver node drains its reader every 1 ms (``batch_period_s``)."""
LATE_READ_NS = 2_000_000
BIN_NS = 1_000_000
LEAD_S = 0.3
"""The emitter starts this long after the reader opened the pty."""


class Schedule(NamedTuple):
    """Words to play: ``due_ns`` from the stream start (non-decreasing) and their bytes."""

    due_ns: np.ndarray
    data: bytes


def worst_case(seconds: float, seed: int = 1) -> Schedule:
    """80 taxels at 4 kHz: 320 words every 1 ms, each at its own time (3.125 us apart)."""
    rng = np.random.default_rng(seed)
    n = int(seconds * 320_000)
    due = (np.arange(n, dtype=np.int64) * 1_000_000_000) // 320_000
    taxel = np.tile(np.arange(1, 81, dtype=np.int64), n // 80 + 1)[:n]
    value = rng.integers(0, 1024, n)
    return Schedule(due, encode_words(taxel, value))


def taps(seconds: float, seed: int = 7) -> Schedule:
    """The tap scene's trials 1 s apart, every word at the time the simulator gives it."""
    from ext_sense_sim.scene import load_scene
    from ext_sense_sim.trial_plan import lay_out_stream

    laid = lay_out_stream(load_scene("tap_rod30_nuskin"), seed, max(1, round(seconds)))
    due = np.concatenate([np.full(len(b) // 4, t, np.int64) for t, b in laid.writes])
    return Schedule(due - due[0], b"".join(b for _, b in laid.writes))


# ------------------------------------------------------------------------------ the emitter
def _emit(master: int, sched: Schedule, t0_ns: int, log_path: str) -> None:
    """Child process: write each word to the pty master once it is due; log every write."""
    got = raise_thread_priority(EMITTER_PRIORITY)
    os.set_blocking(master, True)
    due, data = sched.due_ns, memoryview(sched.data)
    log = []  # (first word, end word, write start ns, write end ns)
    i, n = 0, due.size
    while i < n:
        now = time.monotonic_ns()
        j = int(np.searchsorted(due, now - t0_ns, side="right"))
        if j <= i:
            time.sleep(min(EMIT_PERIOD_S, max(0.0, (t0_ns + int(due[i]) - now) / 1e9)))
            continue
        chunk = data[4 * i : 4 * j]
        while chunk:  # blocks while the pty is full (a reader that is late)
            chunk = chunk[os.write(master, chunk) :]
        log.append((i, j, now, time.monotonic_ns()))
        i = j
        time.sleep(EMIT_PERIOD_S)
    np.save(log_path, np.asarray(log, dtype=np.int64).reshape(-1, 4))
    Path(log_path + ".policy").write_text(got.describe())
    time.sleep(0.5)  # keep the master open until the reader took the last bytes


# ------------------------------------------------------------------------------ one run
def run_once(sched: Schedule, priority: int, tmp: Path, reader_only: bool = False) -> dict:
    """Play ``sched`` into the driver's reader; the stamps against the due times.

    With ``priority`` the reader raises the draining (this, main) thread too, as in the node;
    ``reader_only`` puts that thread back at once (the reader alone at real time).
    """
    main_before = os.sched_getscheduler(0), os.sched_getparam(0).sched_priority, os.nice(0)
    master, slave = os.openpty()
    tty.setraw(slave)
    log_path = str(tmp / f"emit_{os.getpid()}_{time.monotonic_ns()}.npy")
    reader = StreamReader(SerialTransport(os.ttyname(slave), BAUD), priority=priority)
    stream = DriverConfig(baud=BAUD).make_stream()
    reader.start()
    if reader_only:
        _restore(main_before)
    time.sleep(0.1)
    t0 = time.monotonic_ns() + round(LEAD_S * 1e9)
    child = mp.get_context("fork").Process(target=_emit, args=(master, sched, t0, log_path))
    child.start()
    stamps, reads = [], []  # reads: (read ns, words completed)
    end = t0 + int(sched.due_ns[-1]) + 2_000_000_000
    n = sched.due_ns.size
    got = 0
    while got < n and time.monotonic_ns() < end:
        time.sleep(DRAIN_PERIOD_S)
        for chunk in reader.drain():
            block = stream.feed(chunk)
            reads.append((chunk.t_ns, block.t_ns.size))
            stamps.append(block.t_ns)
            got += block.t_ns.size
    child.join(timeout=10)
    reader.stop()
    _restore(main_before)
    for fd in (master, slave):
        os.close(fd)
    writes = np.load(log_path)
    policy = Path(log_path + ".policy").read_text()
    for p in (log_path, log_path + ".policy"):
        os.unlink(p)
    return _figures(sched, t0, np.concatenate(stamps), np.asarray(reads), writes, reader, policy)


def _restore(before: tuple[int, int, int]) -> None:
    """Put the main thread back to its policy, priority and nice (root may raise it back)."""
    os.sched_setscheduler(0, before[0], os.sched_param(before[1]))
    with contextlib.suppress(OSError):
        os.setpriority(os.PRIO_PROCESS, 0, before[2])


def _figures(
    sched: Schedule,
    t0: int,
    stamps: np.ndarray,
    reads: np.ndarray,
    writes: np.ndarray,
    reader: StreamReader,
    emitter_policy: str,
) -> dict:
    n = stamps.size
    due = t0 + sched.due_ns[:n]
    err = stamps - due
    offset = int(np.median(err))
    wrong = np.floor_divide(stamps - offset - t0, BIN_NS) != np.floor_divide(due - t0, BIN_NS)
    read_ns = reads[:, 0]
    first = np.concatenate([[0], np.cumsum(reads[:, 1])[:-1]])
    has = reads[:, 1] > 0
    delay = read_ns[has] - due[first[has]]  # the read's return after its oldest word was due
    gaps = np.diff(read_ns)
    # emitter lag: each write's end after its newest word was due (a full pty blocks it)
    lag = writes[:, 3] - (t0 + sched.due_ns[writes[:, 1] - 1]) if writes.size else np.zeros(1)
    us = 1e-3
    return {
        "words_sent": int(sched.due_ns.size),
        "words_stamped": int(n),
        "reads": int(read_ns.size),
        "read_interval_us": [float(np.percentile(gaps, q)) * us for q in (50, 99, 100)],
        "err_p50_us": float(np.median(err)) * us,
        "abs_err_p99_us": float(np.percentile(np.abs(err), 99)) * us,
        "abs_err_max_us": float(np.abs(err).max()) * us,
        "wrong_bin": float(wrong.mean()),
        "late_reads": int((delay > LATE_READ_NS).sum()),
        "late_read_fraction": float((delay > LATE_READ_NS).mean()),
        "read_delay_quantiles_us": [
            float(np.percentile(delay, q)) * us for q in (0, 10, 25, 50, 75, 90, 95, 99, 99.9, 100)
        ],
        "emitter_lag_p99_us": float(np.percentile(lag, 99)) * us,
        "reader": reader.scheduling.describe() if reader.scheduling else "?",
        "drainer": reader.drainer_scheduling.describe() if reader.drainer_scheduling else "",
        "emitter": emitter_policy,
    }


def _row(stream: str, load: str, sched: str, r: dict) -> str:
    ri = r["read_interval_us"]
    return (
        f"{stream:5s} {load:6s} {sched:8s} | {r['words_stamped']:>8d}/{r['words_sent']:<8d} "
        f"| {ri[0]:7.0f} {ri[1]:7.0f} {ri[2]:8.0f} | {r['err_p50_us']:+7.0f} "
        f"{r['abs_err_p99_us']:7.0f} {r['abs_err_max_us']:8.0f} | {100 * r['wrong_bin']:5.1f} % "
        f"| {r['late_reads']:5d} ({100 * r['late_read_fraction']:4.1f} %) "
        f"| {r['emitter_lag_p99_us']:7.0f} | {r['reader']}"
        + (f"; drainer {r['drainer']}" if sched == "best" else "")
    )


HEADER = (
    "stream load   reader   |  stamped/sent     | read interval us       | stamp error us"
    "          | wrong  | late reads    | emitter | reader thread got\n"
    "                       |                   |     p50     p99      max|     p50     p99"
    "      max | 1 ms   | > 2 ms        | lag p99 |"
)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="2 s per run")
    parser.add_argument("--seconds", type=float, default=0.0, help="seconds per run")
    parser.add_argument("--streams", default="4k,taps", help="comma separated: 4k, taps")
    parser.add_argument("--loads", default="quiet,hog", help="comma separated: quiet, hog")
    parser.add_argument("--priority", type=int, default=BEST_PRIORITY, help="best: FIFO prio")
    parser.add_argument("--json", type=Path, help="also write every figure here")
    args = parser.parse_args()
    seconds = args.seconds or (2.0 if args.quick else 8.0)
    makers = {"4k": worst_case, "taps": taps}
    streams = {s: makers[s](seconds) for s in args.streams.split(",") if s}
    cores = os.cpu_count() or 2
    print(
        f"[arrival] {seconds:g} s per run, {cores} cores, load average "
        f"{os.getloadavg()[0]:.2f} at start; hog = {cores} busy-looping processes",
        flush=True,
    )
    print(HEADER, flush=True)
    results = []
    tmp = Path(os.environ.get("TMPDIR", "/tmp"))
    for load in [s for s in args.loads.split(",") if s]:
        hog = start_hog(cores) if load == "hog" else []
        try:
            time.sleep(0.5 if hog else 0.0)
            for name, sched in streams.items():
                for label, prio, reader_only in (
                    ("default", 0, False),
                    ("reader", args.priority, True),
                    ("best", args.priority, False),
                ):
                    r = run_once(sched, prio, tmp, reader_only)
                    r.update(stream=name, load=load, scheduling=label)
                    r["loadavg_1m"] = os.getloadavg()[0]
                    results.append(r)
                    print(_row(name, load, label, r), flush=True)
        finally:
            stop_hog(hog)
    print(f"[arrival] emitter scheduling: {results[0]['emitter'] if results else '-'}")
    if args.json:
        args.json.write_text(json.dumps(results, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
