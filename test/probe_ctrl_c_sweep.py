"""Ctrl-C of the tap graph's process group at many delays after ``ext-sense run`` started.

``test/test_shutdown.py`` stops the graph at three start-up delays; this probe sweeps many
(a few seconds each, so it stays out of the suite) to find a stage of start-up where a stop is
not clean: the runner importing, node processes importing rclpy, nodes being built and
activated, the first data flowing. Run it as
``.venv/bin/python test/probe_ctrl_c_sweep.py [--delays 0.1,0.5,...] [--repeat N]``; it prints
one line per run with the problems found (empty: clean) and exits 1 if any run was not clean.
A rare outcome needs many runs of one delay: ``--delays 0.04,0.05 --repeat 50`` is 100 runs.
"""

from __future__ import annotations

import argparse
import signal
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).parent))
from sim_models import Graph, stop_problems, train_sim_model

DEFAULT_DELAYS = [0.1 * k for k in range(1, 21)] + [2.4, 2.7, 3.0, 3.5, 4.0]


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--delays", help="comma-separated seconds (default: 0.1 to 4 s)")
    parser.add_argument("--repeat", type=int, default=1, help="runs per delay (default 1)")
    parser.add_argument(
        "--sigint-ignored",
        action="store_true",
        help="start the graph with SIGINT ignored, as a shell without job control does",
    )
    args = parser.parse_args()
    delays = [float(d) for d in args.delays.split(",")] if args.delays else DEFAULT_DELAYS
    delays = [d for d in delays for _ in range(args.repeat)]
    tmp = Path(tempfile.mkdtemp(prefix="ctrl_c_sweep_"))
    model, _ = train_sim_model(tmp, "tap_rod30_nuskin", "tap_localization", 16)
    unclean = 0
    for i, delay in enumerate(delays):
        graph = Graph(
            "trials:=0",
            f"model:={model}",
            f"port:={tmp / f'n{i}.pty'}",
            sigint_ignored=args.sigint_ignored,
        )
        time.sleep(delay)
        took = graph.stop([(0.0, signal.SIGINT)])
        out, err = "".join(graph.out), "".join(graph.err)
        problems = stop_problems(graph.proc, out, err)
        print(f"delay {delay:.3f} s: stopped in {took:.2f} s, problems {problems}", flush=True)
        if problems:
            unclean += 1
            (tmp / f"unclean_{i}_{delay:.3f}.log").write_text(out + err)
    print(f"{unclean} of {len(delays)} runs not clean (logs in {tmp})")
    return 1 if unclean else 0


if __name__ == "__main__":
    sys.exit(main())
