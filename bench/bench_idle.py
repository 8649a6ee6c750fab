"""Idle cost: CPU per node process of a graph with no input (issue #16: at most 1 % of a core).

    python bench/bench_idle.py                          # hot_path:=processes, then one_process
    python bench/bench_idle.py --hot-path processes     # one process per node only
    python bench/bench_idle.py --baseline /tmp/old_src  # also an older source tree, side by side

The ``tap_localization`` graph is started as ``ext-sense run`` starts it (``source:=serial`` on a
pty this script opens and never writes to, the monitor without a trial count, so nothing ends
it); once every node process is up and ``--settle`` seconds have passed, each process's CPU time
(``utime + stime`` of ``/proc/<pid>/stat``, every thread) is read ``--seconds`` apart. The
figure is that CPU time over the wall time, in % of one core. The target is per node: a
``node_group`` process holding n nodes (``hot_path:=one_process``) may use n %. The driver's
link is silent here; a real receiver sends idle words (about 540 words/s), which the driver
then decodes as they come.

``--baseline DIR`` runs the same measurement on another source tree: ``DIR`` holds the package
directories as ``src/`` does (``DIR/ext_sense_perception/ext_sense_perception/...``), put first
on ``PYTHONPATH`` so they shadow the venv's editable installs (messages stay the venv's). The two
runs alternate ``--rounds`` times, so both see the same machine load; the load average is
printed with the figures.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import signal
import subprocess
import sys
import time
import tty
from pathlib import Path

from source_tree import baseline_path

TARGET_PERCENT = 1.0
CLK_TCK = os.sysconf("SC_CLK_TCK")


def cpu_ticks(pid: int) -> int | None:
    """User plus system CPU time of a process (all its threads), clock ticks; None when gone."""
    try:
        fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    except OSError:
        return None
    return int(fields[11]) + int(fields[12])  # utime, stime (fields 14 and 15 of stat)


def children(pid: int) -> list[int]:
    """Direct children of ``pid``."""
    out = []
    for task in Path(f"/proc/{pid}/task").glob("*"):
        with contextlib.suppress(OSError):
            out += [int(p) for p in (task / "children").read_text().split()]
    return out


def process_name(pid: int) -> str:
    """The graph names of the nodes a runner child holds (its JSON payload), else its command."""
    try:
        argv = Path(f"/proc/{pid}/cmdline").read_bytes().split(b"\0")
    except OSError:
        return f"pid {pid}"
    for arg in argv:
        if arg.startswith(b"{"):
            payload = json.loads(arg)
            specs = payload.get("specs") or [payload["spec"]]
            return "+".join(s["name"] for s in specs)
    return Path(argv[0].decode()).name


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
        with contextlib.suppress(ProcessLookupError):
            os.killpg(runner.pid, signal.SIGINT)
        try:
            runner.wait(timeout=20)
        except subprocess.TimeoutExpired:
            with contextlib.suppress(ProcessLookupError):
                os.killpg(runner.pid, signal.SIGKILL)
            runner.wait()
        os.close(master)
        os.close(slave)
    out = {}
    for pid, name in pids.items():
        a, b = start[pid], end[pid]
        out[name] = float("nan") if a is None or b is None else (b - a) / CLK_TCK / wall * 100
    return out


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
