"""CPU cost of the live view: the tap graph with ``view:=true`` beside the same graph without it.

    python bench/bench_view.py            # 15 s warm-up, 60 s measured per configuration
    python bench/bench_view.py --quick    # 8 s and 10 s

The emulated NUSkin's tap graph (``trials:=0``) without the view, with it and no client, and with
a Foxglove protocol client on every channel (``test/foxglove_client.py``): CPU of the view node
and of the rest of the graph (% of one core), frames/s received, and what the view must never
cost perception: bytes the emulated device dropped and contacts the window node lost.
"""

from __future__ import annotations

import argparse
import os
import re
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from common import (
    children,
    cpu_percent,
    cpu_ticks,
    local_ros_domain,
    process_name,
    stop_group,
    tap_model,
)

local_ros_domain()
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "test"))  # foxglove_client

GRAPH = "tap_localization"
DROPPED = re.compile(r"so far: (\d+) bytes dropped")
LOST = re.compile(r"\((\d+) contact\(s\) lost, \d+ degraded\)")
PLAYED = re.compile(r"\[sim_device\]: trial (\d+) ")
ESTIMATED = re.compile(r"^tap +\d+ \(trial (\d+)\)", re.MULTILINE)


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def measure(model: Path, tmp: Path, view: bool, client: bool, warm_s: float, span_s: float) -> dict:
    """One configuration: CPU % of one core of the graph and of the view node, frames/s."""
    port = _free_port()
    args = [sys.executable, "-m", "ext_sense.cli", "run", GRAPH, "trials:=0", f"model:={model}"]
    args += [f"port:={tmp / f'pty_{view}_{client}'}"]
    if view:
        args += ["view:=true", f"view_port:={port}"]
    log = (tmp / f"graph_{view}_{client}.log").open("w+")
    proc = subprocess.Popen(args, stdout=log, stderr=subprocess.STDOUT, start_new_session=True)
    fg = None
    try:
        if client:
            from foxglove_client import FoxgloveClient

            fg = FoxgloveClient(f"ws://127.0.0.1:{port}", connect_timeout_s=60)
        time.sleep(warm_s)
        names = {p: process_name(p) for p in (proc.pid, *children(proc.pid))}
        n0 = len(fg.messages()) if fg else 0
        c0, t0 = {p: cpu_ticks(p) for p in names}, time.monotonic()
        time.sleep(span_s)
        c1, t1 = {p: cpu_ticks(p) for p in names}, time.monotonic()
        n1 = len(fg.messages()) if fg else 0
    finally:
        if fg is not None:
            fg.close()
        stop_group(proc)
    log.seek(0)
    text = log.read()
    log.close()
    wall = t1 - t0
    # the last trial played may still be in its window when the graph is stopped
    played = set(sorted(set(PLAYED.findall(text)), key=int)[:-1])
    per = {names[p]: v for p, v in cpu_percent(c0, c1, wall).items() if v == v}
    return {
        "graph_pct": sum(per.values()),
        "view_pct": per.get("foxglove_view", 0.0),
        "msgs_per_s": (n1 - n0) / wall,
        "nodes": len(per),
        "dropped_bytes": max((int(m) for m in DROPPED.findall(text)), default=0),
        "contacts_lost": max((int(m) for m in LOST.findall(text)), default=0),
        "played": len(played),
        "estimated": len(played & set(ESTIMATED.findall(text))),
    }


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="a small version in seconds")
    parser.add_argument("--model", default="", help="tap model bundle (default: the demo's)")
    args = parser.parse_args()
    warm_s, span_s = (8.0, 10.0) if args.quick else (15.0, 60.0)
    with tempfile.TemporaryDirectory(prefix="bench_view_") as tmp_name:
        tmp = Path(tmp_name)
        model, _ = tap_model(args.model, tmp, 100 if args.quick else 300)
        print(
            f"tap_localization graph on the emulated NUSkin, {span_s:g} s measured after "
            f"{warm_s:g} s; CPU as % of one core (user + system), {os.cpu_count()} cores"
        )
        rows = (
            ("view off", False, False),
            ("view:=true, no client", True, False),
            ("view:=true, client on every channel", True, True),
        )
        base = None
        for label, view, client in rows:
            r = measure(model, tmp, view, client, warm_s, span_s)
            base = r["graph_pct"] if base is None else base
            extra = f"  +{r['graph_pct'] - base:5.1f} vs off" if view else ""
            msgs = f"  client {r['msgs_per_s']:.1f} msgs/s" if client else ""
            rest = r["graph_pct"] - r["view_pct"]
            print(
                f"  {label:38s} view node {r['view_pct']:5.1f} %  rest of the graph {rest:6.1f} %"
                f"{extra}{msgs}  device dropped {r['dropped_bytes']} B, "
                f"{r['contacts_lost']} contacts lost, {r['estimated']} of {r['played']} trials "
                "estimated",
                flush=True,
            )
    return 0


if __name__ == "__main__":
    sys.exit(main())
