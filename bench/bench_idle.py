"""Idle cost: CPU per node process of a graph with no input (issue #16: at most 1 % of a core).

    python bench/bench_idle.py                          # hot_path:=processes, then one_process
    python bench/bench_idle.py --baseline /tmp/old_src  # also an older source tree, side by side

The ``tap_localization`` graph on a pty nobody writes to (``trials:=0``: nothing ends it); after
``--settle`` s each process's CPU time is read ``--seconds`` apart, as % of one core. A process
holding n nodes (``hot_path:=one_process``) may use n %. ``--baseline`` runs alternate with this
tree's ``--rounds`` times, so both see the same load.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
import tty
from pathlib import Path

from common import baseline_path, children, cpu_percent, cpu_ticks, process_name, stop_group

TARGET_PERCENT = 1.0


def measure(
    hot_path: str, seconds: float, settle: float, pythonpath: str | None, domain: int, model: str
) -> dict[str, float]:
    """CPU % of one core per process of the idle tap graph (and its runner)."""
    master, slave = os.openpty()
    tty.setraw(slave)
    env = {**os.environ, "ROS_DOMAIN_ID": str(domain), "ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST"}
    env.pop("PYTHONPATH", None)
    if pythonpath:
        env["PYTHONPATH"] = pythonpath
    cmd = [
        sys.executable,
        "-m",
        "ext_sense.cli",
        "run",
        "tap_localization",
        "source:=serial",
        f"port:={os.ttyname(slave)}",
        "trials:=0",
        f"model:={model}",
    ]
    if hot_path:
        cmd.append(f"hot_path:={hot_path}")
    runner = subprocess.Popen(
        cmd, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, start_new_session=True
    )
    try:
        time.sleep(settle)
        if runner.poll() is not None:
            raise SystemExit(
                f"bench_idle: the graph ended: {runner.stderr.read().decode()[-2000:]}"
            )
        pids = {runner.pid: "runner (ext-sense run)"}
        pids.update({p: process_name(p) for p in children(runner.pid)})
        start = {p: cpu_ticks(p) for p in pids}
        t0 = time.monotonic()
        time.sleep(seconds)
        wall = time.monotonic() - t0
        end = {p: cpu_ticks(p) for p in pids}
    finally:
        stop_group(runner)
        os.close(master)
        os.close(slave)
    return {pids[p]: v for p, v in cpu_percent(start, end, wall).items()}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=10.0, help="measured interval, s")
    parser.add_argument("--settle", type=float, default=12.0, help="wait after the start, s")
    parser.add_argument("--rounds", type=int, default=1, help="alternations with --baseline")
    parser.add_argument(
        "--hot-path",
        default="processes,one_process",
        help="the graph's hot_path values to measure, comma separated",
    )
    parser.add_argument("--baseline", type=Path, help="an older source tree to compare with")
    parser.add_argument("--model", default="", help="tap model bundle (default: the graph's)")
    parser.add_argument("--quick", action="store_true", help="5 s intervals")
    parser.add_argument("--json", type=Path, help="also write the figures here")
    args = parser.parse_args()
    seconds = 5.0 if args.quick else args.seconds
    domain = 150 + os.getpid() % 50
    # named here, so that a --baseline tree outside the checkout loads the same bundle
    from ext_sense_perception.online.model_store import find_model

    model = str(args.model or find_model("", "tap_localization", "nuskin"))
    runs = [(f"hot_path:={h}", None, h) for h in args.hot_path.split(",") if h]
    if args.baseline:
        runs.insert(0, ("baseline", baseline_path(args.baseline), ""))
    results: dict[str, list[dict[str, float]]] = {label: [] for label, _, _ in runs}
    for _ in range(args.rounds):
        for label, path, hot in runs:
            load = os.getloadavg()[0]
            got = measure(hot, seconds, args.settle, path, domain, model)
            results[label].append(got)
            for name, pct in got.items():
                print(f"[idle] {label:<22} {name:<50} {pct:5.2f} % of a core (load {load:.2f})")
    # the target is per node: a process holding n nodes (node_group) may use n times it
    verdict = all(
        pct <= TARGET_PERCENT * (name.count("+") + 1)
        for label, _, _ in runs
        if label != "baseline"
        for name, pct in results[label][-1].items()
        if pct == pct
    )
    print(f"[idle] target <= {TARGET_PERCENT:g} % per node: {'met' if verdict else 'MISSED'}")
    if args.json:
        args.json.write_text(json.dumps(results, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
