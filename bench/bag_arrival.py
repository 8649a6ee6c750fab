"""How late each trial's bytes reached the driver in a live handover bag, against the plan.

    python bench/bag_arrival.py BAG [--seed 11] [--scene handover_rod_nuskin]

BAG is a handover bag of ``bench_live_offline.py --keep`` (raw packets, ground truth, offers).
Its bytes are those the emulated device wrote; the same trials simulated again from the seed
(``bench_live_offline.planned``) say when each byte was due. Per byte: the time its read
returned (the packet's read stamps) minus the time it was due, less the trial's smallest such
delay (the clocks' offset). A trial whose bytes before the onset are late by more than
``--late-ms`` started late: its first bytes reached the driver in a burst the arrival clock
stamps compressed, which a real receiver never sends (``ext_sense_sim.trials_ahead``). Printed
per trial position in its grasp, because the later trials of a grasp are where the emulator
has to simulate several trials at once to find one of the grasp's class.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
from bench_live_offline import grasps_of, planned, read_bag

from ext_sense.topics import SENSOR_PACKETS
from ext_sense_bags import BagReader
from ext_sense_drivers.packets.packet import packet_of

WINDOW_NS = (50_000_000, 250_000_000)
"""The bytes looked at: from this long before each trial's onset to this long after (the
handover window)."""


def per_byte(items: list[tuple[int, bytes]]) -> tuple[bytes, np.ndarray]:
    """The bytes of ``(t_ns, bytes)`` items joined, and each byte's item time."""
    data = b"".join(bytes(b) for _, b in items)
    t = np.repeat(np.array([int(a) for a, _ in items], np.int64), [len(b) for _, b in items])
    return data, t


def bag_reads(bag: Path) -> list[tuple[int, bytes]]:
    """Every read of the bag's NUSkin packets: ``(return time, bytes)``, in time order."""
    reads: list[tuple[int, bytes]] = []
    with BagReader(bag) as reader:
        for _, msg in reader.messages([SENSOR_PACKETS["nuskin"]]):
            reads += [(c.t_ns, c.data) for c in packet_of(msg).reads()]
    return sorted(reads, key=lambda r: r[0])


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("bag", type=Path)
    parser.add_argument("--seed", type=int, default=11, help="the run's simulator seed")
    parser.add_argument("--scene", default="handover_rod_nuskin")
    parser.add_argument("--late-ms", type=float, default=5.0, help="a late start, ms")
    args = parser.parse_args()
    got = read_bag(args.bag)
    if not got["truths"]:
        print(f"bag_arrival: {args.bag} holds no ground truth", file=sys.stderr)
        return 2
    writes, truths = planned(args.scene, args.seed, sorted(t.trial for t in got["truths"]))
    planned_bytes, due = per_byte(writes)
    live_bytes, read_ns = per_byte(bag_reads(args.bag))
    position = {k: i for g in grasps_of(got["truths"], got["offers"]) for i, k in enumerate(g)}
    rows: dict[int, list[float]] = {}
    missing, pos = 0, 0
    for truth in truths:
        lo = int(np.searchsorted(due, truth.onset_ns - WINDOW_NS[0]))
        hi = int(np.searchsorted(due, truth.onset_ns + WINDOW_NS[1]))
        at = live_bytes.find(planned_bytes[lo : lo + 64], pos)
        if hi - lo < 64 or at < 0 or live_bytes[at : at + hi - lo] != planned_bytes[lo:hi]:
            missing += 1
            continue
        pos = at
        delay_ms = (read_ns[at : at + hi - lo] - due[lo:hi]) / 1e6
        delay_ms -= delay_ms.min()
        before = due[lo:hi] < truth.onset_ns
        rows.setdefault(position.get(truth.trial, -1), []).append(
            float(delay_ms[before].mean()) if before.any() else float("nan")
        )
    print(f"{args.bag}: {len(truths) - missing} trials matched byte for byte, {missing} not")
    for k in sorted(rows):
        a = np.array(rows[k])
        late = a[a > args.late_ms]
        worst = f", worst {late.max():.0f} ms" if late.size else ""
        print(
            f"  trial {k + 1} of its grasp: {late.size} of {a.size} started > {args.late_ms:g} ms "
            f"late{worst}; bytes before the onset late by {np.nanmedian(a):.2f} ms (median)"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
