"""Raw packets at the worst case: 80 taxels at 4 kHz for 60 s through the graph (issue #16).

The tap graph's serial driver and window node on a pty, and ``ext-sense record`` on the
packets. Printed: packets lost by ``seq`` at the window node (target 0) and in the bag, CPU per
process, and bag bytes per minute beside the same stream as decoded ``TaxelEventBatch`` arrays.
``--quick`` streams 10 s; ``--seconds S`` sets the time.
"""

from __future__ import annotations

import argparse
import shutil
import sys
import tempfile
from pathlib import Path

import numpy as np
from common import PACKETS, worst_case_run


def _dir_bytes(path: Path) -> int:
    return sum(p.stat().st_size for p in path.rglob("*") if p.is_file())


def decoded_bag(packet_bag: Path, out: Path) -> int:
    """Write the packet bag's stream as decoded ``TaxelEventBatch`` messages; their count."""
    from ext_sense_bags import BagReader, BagWriter, taxel_event_batch
    from ext_sense_drivers.packets import make_decoder

    n = 0
    with BagReader(packet_bag) as bag, BagWriter(out) as writer:
        decoder = None
        for rec, msg in bag.messages([PACKETS]):
            if decoder is None:
                decoder = make_decoder(msg.encoding, msg.encoding_options)
            d = decoder.decode(msg)
            if not d.events.size:
                continue
            first = int(d.events.t_ns.min())
            batch = taxel_event_batch(
                first,
                d.events.taxel,
                d.events.polarity,
                d.events.value,
                d.events.t_ns - first,
                flag=d.flag,
            )
            writer.write("/extsense/nuskin/events", rec.log_time_ns, batch)
            n += 1
    return n


def run(seconds: float) -> dict:
    """Stream, record, measure; the figures as a dict."""
    tmp = Path(tempfile.mkdtemp(prefix="bench_packets_"))
    bag = tmp / "packets"
    got = worst_case_run(seconds, bag=bag)
    diag, sent, wall = got["diag"], got["words_sent"], got["write_wall_s"]
    from ext_sense_bags import BagReader

    with BagReader(bag) as reader:
        seqs = np.array([int(m.seq) for _, m in reader.messages([PACKETS])], np.int64)
    bag_lost = int(seqs.max() - seqs.min() + 1 - len(np.unique(seqs))) if len(seqs) else -1
    n_decoded = decoded_bag(bag, tmp / "decoded")
    per_min = 60.0 / seconds
    packet_bytes, decoded_bytes = _dir_bytes(bag), _dir_bytes(tmp / "decoded")
    shutil.rmtree(tmp, ignore_errors=True)  # 340 MB at 60 s
    win = diag.get("contact_window: windows", {})
    return {
        "seconds": seconds,
        "write_wall_s": wall,
        "words_sent": sent,
        "events_at_window_node": int(win.get("events_total", -1)),
        "packets_published": int(diag.get("nuskin_driver: link", {}).get("packets_published", -1)),
        "packets_at_window_node": int(win.get("packet_packets", -1)),
        "lost_at_window_node": int(win.get("packet_lost_packets", -1)),
        "packets_in_bag": len(seqs),
        "lost_in_bag": bag_lost,
        "cpu_percent": got["cpu_percent"],
        "packet_bag_mb_per_min": packet_bytes * per_min / 1e6,
        "decoded_bag_mb_per_min": decoded_bytes * per_min / 1e6,
        "decoded_messages": n_decoded,
    }


def main() -> int:
    """Run and print the figures side by side."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--quick", action="store_true", help="stream 10 s instead of 60")
    parser.add_argument("--seconds", type=float, default=None)
    args = parser.parse_args()
    seconds = args.seconds or (10.0 if args.quick else 60.0)
    r = run(seconds)
    print(
        f"80 taxels at 4 kHz for {r['seconds']:.0f} s through packets "
        f"(written in {r['write_wall_s']:.2f} s): {r['words_sent']} words sent, "
        f"{r['events_at_window_node']} events decoded at the window node"
    )
    print(
        f"packets: published {r['packets_published']}, at window node "
        f"{r['packets_at_window_node']}, lost by seq at window node {r['lost_at_window_node']} "
        f"(target 0), in bag {r['packets_in_bag']}, lost by seq in bag {r['lost_in_bag']}"
    )
    cpu = ", ".join(f"{name} {v:.1f}%" for name, v in sorted(r["cpu_percent"].items()))
    print(f"CPU per process (% of one core): {cpu}")
    print(
        f"bag bytes per minute: packets {r['packet_bag_mb_per_min']:.1f} MB | decoded arrays "
        f"(TaxelEventBatch) {r['decoded_bag_mb_per_min']:.1f} MB "
        f"({r['decoded_bag_mb_per_min'] / max(r['packet_bag_mb_per_min'], 1e-9):.2f}x)"
    )
    return 0 if r["lost_at_window_node"] == 0 else 1


if __name__ == "__main__":
    sys.exit(main())
