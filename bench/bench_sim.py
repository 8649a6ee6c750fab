"""Benchmark of the scene simulator: NUSkin rod taps of 300 ms on one core.

Target (issue 5): 1000 taps in at most 60 s. Prints the total, the rate, the ratio to the
target, and the cost of each effect measured in the same run.

    python bench/bench_sim.py            # 1000 taps of tap_rod30_nuskin
    python bench/bench_sim.py --quick    # 100 taps, a few seconds
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")  # one core, as the target says

import argparse  # noqa: E402
import time  # noqa: E402

from ext_sense_sim.dataset import DatasetCollector  # noqa: E402
from ext_sense_sim.engine import Simulator  # noqa: E402
from ext_sense_sim.scene import load_scene  # noqa: E402

TARGET_S_PER_1000 = 60.0


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="100 taps instead of 1000")
    parser.add_argument("--scene", default="tap_rod30_nuskin")
    args = parser.parse_args()
    n = 100 if args.quick else 1000
    scene = load_scene(args.scene)
    sim = Simulator(scene)
    collector = DatasetCollector(scene, 0)
    start, cpu_start = time.perf_counter(), time.process_time()
    events = 0
    for tb, signals in sim.batches(n, 0):
        collector.add(tb, signals)
        _trial, block = signals["events"]
        events += block.size
    total = time.perf_counter() - start
    cpu = time.process_time() - cpu_start
    per_1000 = cpu * 1000 / n  # CPU time of this one-threaded process: its cost on one core
    print(
        f"scene {scene.name}: {n} taps of {scene.trial_s * 1e3:.0f} ms at "
        f"{scene.rate_hz:.0f} Hz, batch {scene.batch_size}, one core"
    )
    print(
        f"wall {total:.2f} s, CPU {cpu:.2f} s (wall exceeds CPU when other processes share "
        f"the cores)"
    )
    print(
        f"CPU {per_1000:.1f} s per 1000 taps; target {TARGET_S_PER_1000:.0f} s "
        f"-> ratio {per_1000 / TARGET_S_PER_1000:.2f} ({'PASS' if per_1000 <= 60 else 'FAIL'})"
    )
    print(f"events {events} ({events / n:.0f} per tap)")
    print(f"{'effect':24s} {'calls':>6s} {'wall_s':>8s} {'cpu_s':>8s} {'cpu share':>9s}")
    accounted = 0.0
    for name, st in sim.stats.items():
        accounted += st.cpu_seconds
        print(
            f"{name:24s} {st.calls:6d} {st.seconds:8.3f} {st.cpu_seconds:8.3f} "
            f"{st.cpu_seconds / cpu:9.1%}"
        )
    rest = cpu - accounted
    print(f"{'(batching, collection)':24s} {'':6s} {'':8s} {rest:8.3f} {rest / cpu:9.1%}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
