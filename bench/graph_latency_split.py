"""Where a live graph's final estimates spend their latency, read from a recorded bag.

``bench_runtime.py --hops`` splits the latency of the bench's own stream; this splits that of
a real graph (simulated device on a pty, the driver process, the nodes), which runs slower
(docs/runtime.md, "Latency on the packet path", run 6). Record the driver's packets, the
windows and the estimates while the graph runs, then read the bag::

    ext-sense record BAG --topics /extsense/nuskin/packets /extsense/contact_window \\
        /extsense/contact_estimate &
    ext-sense run tap_localization trials:=30
    # Ctrl-C the recorder, then
    python bench/graph_latency_split.py BAG

Per final window (times in ms from the window's end, onset + post on the driver's stream
clock): the stamp of the first packet whose stream time reaches the end (the "closer": data,
or an empty "nothing read" packet), when the recorder received that packet, the window, and the
estimate; and the estimate's own ``compute_latency``. The recorder's receive times include
its own hop, the same for every topic.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

PACKETS = "/extsense/nuskin/packets"
WINDOWS = "/extsense/contact_window"
ESTIMATES = "/extsense/contact_estimate"
MS = 1e6


def split(bag: Path) -> dict[str, np.ndarray]:
    """Per final window with a closer and an estimate: each span, ms (see module docstring)."""
    from ext_sense_bags import BagReader
    from ext_sense_drivers.packets import make_decoder
    from ext_sense_runtime.records import estimate_of
    from ext_sense_runtime.stamps import stamp_to_ns

    received, stamps, complete, empty = [], [], [], []
    decoder = None
    with BagReader(bag) as reader:
        for rec, msg in reader.messages([PACKETS]):
            if decoder is None:
                decoder = make_decoder(str(msg.encoding), str(msg.encoding_options))
            received.append(rec.log_time_ns)
            stamps.append(stamp_to_ns(msg.header.stamp))
            complete.append(decoder.decode(msg).complete_ns)
            empty.append(len(msg.data) == 0)
        windows = {
            stamp_to_ns(msg.header.stamp): (
                rec.log_time_ns,
                stamp_to_ns(msg.header.stamp) + int(msg.post_onset_ns),
            )
            for rec, msg in reader.messages([WINDOWS])
            if not msg.provisional
        }
        estimates = {}
        for rec, msg in reader.messages([ESTIMATES]):
            est = estimate_of(msg)
            if not est.provisional:
                estimates[est.onset_ns] = (rec.log_time_ns, est.compute_latency_ns)
    complete_ns = np.asarray(complete, dtype=np.int64)
    rows = []
    for onset, (window_at, end) in sorted(windows.items()):
        i = int(np.searchsorted(complete_ns, end))
        if i == len(complete_ns) or onset not in estimates:
            continue
        estimate_at, latency = estimates[onset]
        rows.append(
            (
                stamps[i] - end,
                received[i] - end,
                window_at - end,
                estimate_at - end,
                latency,
                empty[i],
            )
        )
    if not rows:
        raise SystemExit(f"{bag}: no final window with its closing packet and estimate")
    table = np.asarray(rows, dtype=np.float64)
    return {
        "end -> closer stamped": table[:, 0] / MS,
        "closer stamped -> received": (table[:, 1] - table[:, 0]) / MS,
        "closer received -> window received": (table[:, 2] - table[:, 1]) / MS,
        "window received -> estimate received": (table[:, 3] - table[:, 2]) / MS,
        "compute_latency": table[:, 4] / MS,
        "closed by a 'nothing read' packet": table[:, 5],
    }


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("bag", type=Path)
    spans = split(parser.parse_args().bag)
    n = len(spans["compute_latency"])
    for name, values in spans.items():
        if name.startswith("closed"):
            print(f"{name}: {int(values.sum())} of {n}")
        else:
            print(f"{name}: p50 {np.median(values):.2f} ms, max {values.max():.2f} ms")
    return 0


if __name__ == "__main__":
    sys.exit(main())
