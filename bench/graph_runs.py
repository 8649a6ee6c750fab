"""Part of a node graph started as ``ext-sense run`` starts it, for the benchmarks.

``python bench/graph_runs.py JSON`` is the graph's process: ``ext_sense.runner.run_graph`` on
the nodes of one graph named in ``JSON`` (``{"graph", "overrides", "names"}``), leaving out the
nodes a benchmark replaces (it is their source). It runs in a fresh interpreter, not a
``multiprocessing`` child, so that ``--baseline``'s ``PYTHONPATH`` really gives it the other
source tree (a ``multiprocessing`` child is handed the parent's ``sys.path``). ``run_graph``
spawns each node (or process group) and stops them all (SIGINT) when this process gets SIGINT.
"""

from __future__ import annotations

import dataclasses
import json
import os
import signal
import subprocess
import sys
import threading
from collections.abc import Callable
from pathlib import Path
from typing import Any

STOP_TIMEOUT_S = 15.0


def spin_in_background(node: Any) -> Callable[[], None]:
    """Spin ``node`` on its own executor thread; returns the function that stops and joins it.

    The benchmarks' own nodes (the sensor's stand-in, the estimates' receiver) spin so while
    their main thread keeps the stream's pace.
    """
    from ext_sense_runtime.executor import make_executor

    executor = make_executor()
    executor.add_node(node)
    stop = threading.Event()
    thread = threading.Thread(
        target=lambda: [executor.spin_once(timeout_sec=0.01) for _ in iter(stop.is_set, True)],
        daemon=True,
    )
    thread.start()

    def halt() -> None:
        stop.set()
        thread.join(timeout=2)

    return halt


def start_graph(
    graph: str, overrides: dict[str, str], names: tuple[str, ...], pythonpath: str | None = None
) -> subprocess.Popen[bytes]:
    """Start the nodes ``names`` of ``graph`` for these launch arguments (checked here first).

    Args:
        graph: The graph's name in ``ext_sense.graphs.GRAPHS``.
        overrides: Its launch arguments.
        names: The nodes to start.
        pythonpath: Another source tree's packages first on the path of the graph's processes
            (``--baseline``); that tree's graph description is then the one used.
    """
    from ext_sense.graphs import GRAPHS

    if pythonpath is None:
        built = {n.name for n in GRAPHS[graph].nodes(overrides)}
        if not set(names) <= built:
            raise SystemExit(
                f"graph {graph!r} with {overrides} has no nodes "
                f"{sorted(set(names) - built)}; it has {sorted(built)}"
            )
    env = dict(os.environ)
    if pythonpath is not None:
        env["PYTHONPATH"] = pythonpath
    payload = json.dumps({"graph": graph, "overrides": overrides, "names": list(names)})
    return subprocess.Popen([sys.executable, str(Path(__file__).resolve()), payload], env=env)


def watch_diagnostics(node: Any) -> dict[str, dict[str, str]]:
    """Keep the newest values of every ``/diagnostics`` status the graph publishes.

    Returns:
        Status name -> its key/value pairs, filled in as ``node`` spins.
    """
    from diagnostic_msgs.msg import DiagnosticArray

    from ext_sense_runtime.qos import DIAGNOSTICS_QOS

    diag: dict[str, dict[str, str]] = {}

    def on_diag(msg: DiagnosticArray) -> None:
        for st in msg.status:
            diag[st.name] = {kv.key: kv.value for kv in st.values}

    node.create_subscription(DiagnosticArray, "/diagnostics", on_diag, DIAGNOSTICS_QOS)
    return diag


def stop_graph(proc: subprocess.Popen[bytes]) -> None:
    """SIGINT to the runner (it forwards SIGINT to every node), then wait; kill as last resort."""
    if proc.poll() is None:
        proc.send_signal(signal.SIGINT)
    try:
        proc.wait(timeout=STOP_TIMEOUT_S)
    except subprocess.TimeoutExpired:
        proc.kill()
        proc.wait(timeout=5)


def main() -> int:
    """The graph's process: ``run_graph`` on the named nodes."""
    from ext_sense.graphs import GRAPHS
    from ext_sense.runner import run_graph

    payload = json.loads(sys.argv[1])
    graph, names = GRAPHS[payload["graph"]], set(payload["names"])
    part = dataclasses.replace(
        graph, build=lambda values: tuple(n for n in graph.build(values) if n.name in names)
    )
    return run_graph(part, payload["overrides"])


if __name__ == "__main__":
    sys.exit(main())
