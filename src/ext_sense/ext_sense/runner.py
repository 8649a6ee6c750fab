"""Running a node graph without ``ros2 launch``: the node specs the launch files use.

Each node, or each process group (:mod:`ext_sense.graph_process`), runs in a child ``python -m
ext_sense.runner JSON`` (the ``node_group`` console script). A stop signal is forwarded as one
SIGINT; a child not gone ``STOP_GRACE_S`` later is killed; children get SIGTERM should the
runner die (``PR_SET_PDEATHSIG``).
"""

from __future__ import annotations

import contextlib
import ctypes
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
from ext_sense.graph_process import process_groups
from ext_sense_runtime.stop import (
    STACKS_SIGNAL,
    install_stop_handlers,
    stop_signals_blocked,
)

STOP_GRACE_S = 5.0
STACKS_WAIT_S = 0.5
"""Time a node that did not stop is given to print its threads' stacks before it is killed."""
SUPERVISOR_ENV = "EXT_SENSE_SUPERVISOR_PID"
"""Set in a child's environment to the pid of the process that started it (the runner)."""
_PR_SET_PDEATHSIG = 1


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


def _make_node(spec: NodeSpec, node_class: type, use_sim_time: bool, context: Any = None) -> Any:
    """Construct the node; a managed lifecycle node is then configured and activated."""
    node = node_class(**_node_kwargs(spec, use_sim_time, context))
    if spec.lifecycle and spec.manage:
        from rclpy.lifecycle import TransitionCallbackReturn

        if node.trigger_configure() == TransitionCallbackReturn.SUCCESS:
            node.trigger_activate()
    return node


def run_one(spec: NodeSpec, use_sim_time: bool) -> int:
    """Start one node in this process and spin it until shutdown (the child side)."""
    from ext_sense_runtime.node_main import run_node

    if _stopped_while_starting():
        return 0
    node_class = spec.node_class()
    return run_node(lambda: _make_node(spec, node_class, use_sim_time), args=[])


def run_in_process(nodes: Sequence[NodeSpec], use_sim_time: bool, args: Sequence[str] = ()) -> int:
    """Every node on one executor in this process; ``args``: process-wide ``--ros-args ...``."""
    from ext_sense_runtime import intra_process
    from ext_sense_runtime.node_main import run_nodes

    if _stopped_while_starting():
        return 0
    classes = [(spec, spec.node_class()) for spec in nodes]
    intra_process.enable()  # the hot path's packets and windows go from callback to callback
    return run_nodes(
        [lambda s=spec, c=cls: _make_node(s, c, use_sim_time) for spec, cls in classes],
        args=["node_group", *args] if args else [],
    )


def _stopped_while_starting() -> bool:
    """Install a node process's stop handlers; whether a stop came while it started."""
    stop = install_stop_handlers()
    supervisor = os.environ.pop(SUPERVISOR_ENV, "")  # not for processes this one starts
    if supervisor.isdigit():
        with contextlib.suppress(OSError, AttributeError):  # not Linux: left to the supervisor
            ctypes.CDLL(None, use_errno=True).prctl(_PR_SET_PDEATHSIG, int(signal.SIGTERM))
        if os.getppid() != int(supervisor):  # it died before the request was in place
            os.kill(os.getpid(), signal.SIGTERM)
    if stop.requested():  # held while starting (see spawn_node)
        stop.ignore_further()  # the runner's forwarded SIGINT may still come, during exit
    return stop.requested()


def spawn_node(spec: NodeSpec, use_sim_time: bool) -> subprocess.Popen[bytes]:
    """Start a node process with the stop signals blocked until it installs its handlers."""
    return _spawn(json.dumps({"spec": asdict(spec), "use_sim_time": use_sim_time}))


def group_payload(specs: Sequence[NodeSpec], use_sim_time: bool) -> str:
    """The JSON argument of ``node_group`` (and of ``python -m ext_sense.runner``)."""
    return json.dumps({"specs": [asdict(s) for s in specs], "use_sim_time": use_sim_time})


def _spawn(payload: str) -> subprocess.Popen[bytes]:
    env = {**os.environ, "PYTHONUNBUFFERED": "1", SUPERVISOR_ENV: str(os.getpid())}
    with stop_signals_blocked():
        return subprocess.Popen([sys.executable, "-m", "ext_sense.runner", payload], env=env)


def stop_nodes(procs: dict[str, subprocess.Popen[bytes]], log: Any) -> dict[str, int]:
    """SIGINT to every child still running, SIGKILL to any not gone after ``STOP_GRACE_S``.

    Returns every child's exit code (negative: the signal that ended it).
    """
    for proc in procs.values():
        if proc.poll() is None:
            proc.send_signal(signal.SIGINT)
    deadline = time.monotonic() + STOP_GRACE_S
    for name, proc in procs.items():
        try:
            proc.wait(timeout=max(0.0, deadline - time.monotonic()))
        except subprocess.TimeoutExpired:
            print(
                f"[run] {name} did not stop within {STOP_GRACE_S:g} s: its threads' stacks "
                "(on its stderr), then killed",
                file=log,
            )
            with contextlib.suppress(OSError):
                proc.send_signal(STACKS_SIGNAL)
                time.sleep(STACKS_WAIT_S)
            proc.kill()
            proc.wait()
    return {name: proc.returncode for name, proc in procs.items()}


def exit_status(code: int) -> int:
    """A child's exit code as a process exit status: ``128 + N`` for death by signal N."""
    return 128 - code if code < 0 else code


def run_graph(
    graph: GraphSpec, overrides: dict[str, str], in_process: bool = False, log: Any = None
) -> int:
    """Start every node of ``graph`` and supervise them until done.

    Returns 0 when every node exited with 0; else the exit status of the first node that failed
    while running or, failing that, of the first that did not exit with 0 when stopped.
    """
    values = graph.resolve(overrides)
    nodes = graph.build(values)
    use_sim_time = as_bool(values["use_sim_time"])
    log = log or sys.stderr
    if in_process:
        return run_in_process(nodes, use_sim_time)

    procs: dict[str, subprocess.Popen[bytes]] = {}
    stop = install_stop_handlers()
    rc = 0
    try:
        for name, specs in process_groups(nodes):
            if stop.requested():
                break
            if len(specs) == 1:
                spec = specs[0]
                procs[name] = spawn_node(spec, use_sim_time)
                print(f"[run] started {spec.name} ({spec.package}/{spec.executable})", file=log)
            else:
                procs[name] = _spawn(group_payload(specs, use_sim_time))
                held = " ".join(s.name for s in specs)
                print(f"[run] started {name}: {held} in one process (node_group)", file=log)
        required = {name for name, specs in process_groups(nodes) if any(s.required for s in specs)}
        while not stop.requested():
            time.sleep(0.05)
            finished = {n: p.returncode for n, p in procs.items() if p.poll() is not None}
            failed = {n: c for n, c in finished.items() if c != 0}
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
        codes = stop_nodes(procs, log)
        stop.ignore_further()  # the graph is down: a second Ctrl-C must not kill this process
    if codes:
        listed = " ".join(f"{name}={code}" for name, code in codes.items())
        print(f"[run] exit codes: {listed}", file=log)
    if rc == 0:
        rc = next((code for code in codes.values() if code != 0), 0)
    return exit_status(rc)


def _spec_from_json(raw: dict[str, Any]) -> NodeSpec:
    return NodeSpec(
        **{**raw, "remappings": tuple(tuple(r) for r in raw["remappings"])}  # JSON lists
    )


def main(argv: Sequence[str] | None = None) -> int:
    """Child entry point and ``node_group``: ``NODE_JSON|GROUP_JSON [--ros-args ...]``."""
    argv = list(sys.argv[1:] if argv is None else argv)
    payload = json.loads(argv[0])
    use_sim_time = bool(payload["use_sim_time"])
    if "specs" in payload:
        specs = [_spec_from_json(raw) for raw in payload["specs"]]
        return run_in_process(specs, use_sim_time, argv[1:])
    return run_one(_spec_from_json(payload["spec"]), use_sim_time)


if __name__ == "__main__":
    sys.exit(main())
