"""Running a node graph without ``ros2 launch``: one process per node, like launch does.

``ext-sense run GRAPH name:=value ...`` resolves the graph's arguments, builds its node specs
with the same function the launch files use, and starts each node in its own Python process
(``python -m ext_sense.runner NODE_JSON``), so the graph uses every core and a crash stays in one
node. The runner supervises the children: Ctrl-C or SIGTERM is forwarded as SIGINT, and when a
node marked ``required`` exits the others are stopped (launch's ``Shutdown``).

``--in-process`` instead adds every node to one executor in this process, which is handy for
debugging with a single interpreter.

A node that has finished its job (e.g. the estimate monitor after N taps) ends its process by
shutting down its context: ``rclpy.try_shutdown(context=node.context)``.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from collections.abc import Sequence
from dataclasses import asdict
from typing import Any

from ext_sense.graph import GraphSpec, NodeSpec, as_bool

STOP_GRACE_S = 5.0


def _node_kwargs(spec: NodeSpec, use_sim_time: bool, context: Any = None) -> dict[str, Any]:
    """Keyword arguments for ``NodeClass(**kwargs)``: overrides, and name/remaps as ROS args."""
    from rclpy.parameter import Parameter

    overrides = [Parameter(k, value=v) for k, v in spec.parameters.items()]
    overrides.append(Parameter("use_sim_time", value=use_sim_time))
    kwargs: dict[str, Any] = {
        "parameter_overrides": overrides,
        "cli_args": spec.ros_args(),
    }
    if context is not None:
        kwargs["context"] = context
    return kwargs


def run_one(spec: NodeSpec, use_sim_time: bool) -> int:
    """Start one node in this process and spin it until shutdown (the child side)."""
    from ext_sense_runtime.node_main import run_node

    node_class = spec.node_class()
    return run_node(lambda: node_class(**_node_kwargs(spec, use_sim_time)), args=[])


def run_in_process(nodes: Sequence[NodeSpec], use_sim_time: bool) -> int:
    """Every node on one executor in this process; stops when any node shuts the context."""
    import rclpy
    from rclpy.executors import ExternalShutdownException

    from ext_sense_runtime.executor import make_executor, spin_until_shutdown

    rclpy.init(args=[])
    created = []
    try:
        executor = make_executor()
        for spec in nodes:
            node = spec.node_class()(**_node_kwargs(spec, use_sim_time))
            created.append(node)
            executor.add_node(node)
        spin_until_shutdown(executor)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        for node in created:
            node.destroy_node()
        rclpy.try_shutdown()
    return 0


def _spawn(spec: NodeSpec, use_sim_time: bool) -> subprocess.Popen[bytes]:
    payload = json.dumps({"spec": asdict(spec), "use_sim_time": use_sim_time})
    env = {**os.environ, "PYTHONUNBUFFERED": "1"}
    return subprocess.Popen([sys.executable, "-m", "ext_sense.runner", payload], env=env)


def _stop(procs: dict[str, subprocess.Popen[bytes]]) -> None:
    for proc in procs.values():
        if proc.poll() is None:
            proc.send_signal(signal.SIGINT)
    deadline = time.monotonic() + STOP_GRACE_S
    for proc in procs.values():
        try:
            proc.wait(timeout=max(0.0, deadline - time.monotonic()))
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()


def run_graph(
    graph: GraphSpec, overrides: dict[str, str], in_process: bool = False, log: Any = None
) -> int:
    """Start every node of ``graph`` and supervise them until done.

    Returns:
        0 when stopped by a signal or when every required node exited with 0; otherwise the
        exit code of the first node that failed.
    """
    values = graph.resolve(overrides)
    nodes = graph.build(values)
    use_sim_time = as_bool(values["use_sim_time"])
    log = log or sys.stderr
    if in_process:
        return run_in_process(nodes, use_sim_time)

    procs: dict[str, subprocess.Popen[bytes]] = {}
    stopping = False

    def _on_signal(signum: int, _frame: Any) -> None:
        nonlocal stopping
        stopping = True

    previous = {s: signal.signal(s, _on_signal) for s in (signal.SIGINT, signal.SIGTERM)}
    rc = 0
    try:
        for spec in nodes:
            procs[spec.name] = _spawn(spec, use_sim_time)
            print(f"[run] started {spec.name} ({spec.package}/{spec.executable})", file=log)
        required = {s.name for s in nodes if s.required}
        while not stopping:
            time.sleep(0.05)
            finished = {n: p.returncode for n, p in procs.items() if p.poll() is not None}
            failed = {n: c for n, c in finished.items() if c not in (0, -signal.SIGINT)}
            if failed:
                name, rc = next(iter(failed.items()))
                print(f"[run] {name} exited with {rc}; stopping the graph", file=log)
                break
            if required and required <= finished.keys():
                print("[run] required nodes finished; stopping the graph", file=log)
                break
            if len(finished) == len(procs):
                break
    finally:
        _stop(procs)
        for s, handler in previous.items():
            signal.signal(s, handler)
    return rc


def main(argv: Sequence[str] | None = None) -> int:
    """Child entry point: ``python -m ext_sense.runner NODE_JSON``."""
    argv = list(sys.argv[1:] if argv is None else argv)
    payload = json.loads(argv[0])
    raw = payload["spec"]
    spec = NodeSpec(
        **{**raw, "remappings": tuple(tuple(r) for r in raw["remappings"])}  # JSON lists
    )
    return run_one(spec, bool(payload["use_sim_time"]))


if __name__ == "__main__":
    sys.exit(main())
