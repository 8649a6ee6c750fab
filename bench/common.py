"""What the benchmarks share: graphs started as ``ext-sense run`` starts them, CPU hogs,
per-process CPU time, an older source tree (``--baseline``) and the tap model they serve.

``python bench/common.py JSON`` is a graph's process (:func:`start_graph`): a fresh
interpreter, so that ``--baseline``'s ``PYTHONPATH`` really gives it the other source tree.
"""

from __future__ import annotations

import contextlib
import dataclasses
import json
import os
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

CLK_TCK = os.sysconf("SC_CLK_TCK")
PACKETS = "/extsense/nuskin/packets"


def local_ros_domain() -> None:
    """Keep this process's ROS traffic on this host, in a domain of its own (unless set)."""
    os.environ.setdefault("ROS_DOMAIN_ID", str(100 + os.getpid() % 100))
    os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")


def pct(values: list[float]) -> tuple[float, float]:
    """p50 and p99 of ``values`` (NaN when empty)."""
    a = np.asarray(values, dtype=np.float64)
    if not a.size:
        return float("nan"), float("nan")
    return float(np.percentile(a, 50)), float(np.percentile(a, 99))


def synthetic_taps(n: int, seed: int = 0) -> Any:
    """Windows (n, 80, 300) at 1 ms: each finger rings at a frequency set by the tap position."""
    from ext_sense_perception.data.window_set import WindowSet
    from ext_sense_perception.online.model_input import Geometry
    from ext_sense_runtime.stamps import MS

    rng = np.random.default_rng(seed)
    y = rng.uniform(0.02, 0.28, n)
    t = np.arange(300)
    x = np.zeros((n, 80, 300), np.float32)
    for i in range(n):
        f = 40 + 400 * y[i]
        ring = (
            np.sin(2 * np.pi * f * (t - 50) / 1000.0)
            * np.exp(-np.maximum(t - 50, 0) / 60.0)
            * (t >= 50)
        )
        gain = rng.uniform(0.5, 3.0, (80, 1))
        x[i] = np.round(gain * ring + rng.normal(0, 0.3, (80, 300)))
    g = Geometry(80, 300, MS, 50 * MS, "nuskin")
    return WindowSet(
        "tap_localization",
        "nuskin",
        x,
        y,
        g,
        (),
        np.arange(n),
        np.full(n, 0.3),
        "synthetic",
        "none",
    )


# ------------------------------------------------------------------------------ processes
def start_hog(n: int) -> list[subprocess.Popen[bytes]]:
    """``n`` busy-looping processes (one per core keeps both cores busy)."""
    return [subprocess.Popen([sys.executable, "-c", "while True: pass"]) for _ in range(n)]


def stop_hog(procs: list[subprocess.Popen[bytes]]) -> None:
    """Stop the hog's processes (by their own pids)."""
    for p in procs:
        if p.poll() is None:
            p.send_signal(signal.SIGTERM)
    for p in procs:
        try:
            p.wait(timeout=5)
        except subprocess.TimeoutExpired:
            p.kill()
            p.wait(timeout=5)


def stop_group(proc: subprocess.Popen, timeout: float = 20.0) -> None:
    """SIGINT to a child's process group (a graph's runner and its nodes), SIGKILL if stuck."""
    if proc.poll() is None:
        with contextlib.suppress(ProcessLookupError):
            os.killpg(proc.pid, signal.SIGINT)
    try:
        proc.wait(timeout=timeout)
    except subprocess.TimeoutExpired:
        with contextlib.suppress(ProcessLookupError):
            os.killpg(proc.pid, signal.SIGKILL)
        proc.wait(timeout=5)


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


def cpu_percent(start: dict[int, int | None], end: dict[int, int | None], wall: float) -> dict:
    """pid -> % of one core between two :func:`cpu_ticks` readings (NaN when it ended)."""
    return {
        p: float("nan")
        if start[p] is None or end[p] is None
        else (end[p] - start[p]) / CLK_TCK / wall * 100
        for p in start
    }


def baseline_path(root: Path) -> str:
    """``PYTHONPATH`` putting the package directories of the source tree ``root`` first.

    Before/after figures are taken side by side in one run (the shared machine's load moves by
    the minute); the messages stay the venv's.
    """
    dirs = [str(p) for p in sorted(root.resolve().glob("ext_sense*")) if (p / p.name).is_dir()]
    if not dirs:
        raise SystemExit(f"--baseline {root}: no package directories there")
    return os.pathsep.join(dirs)


def tap_model(model: str, tmp: Path, train_taps: int) -> tuple[Path, str]:
    """The tap bundle to serve and how it was found: ``model``, the demo's, or trained here."""
    from ext_sense_perception.errors import PerceptionError
    from ext_sense_perception.online.model_store import find_model
    from ext_sense_sim.default_models import ensure_model

    if model:
        path = Path(model).resolve()
        if not (path / "model_card.json").is_file():
            raise SystemExit(f"--model {model}: no model_card.json there")
        return path, str(path)
    try:
        default = find_model("", "tap_localization", "nuskin")
        return default, f"{default} (the demo's)"
    except PerceptionError as err:
        missing = str(err)
    out = tmp / "model"
    t0 = time.monotonic()
    ensure_model(
        out, "tap_localization", "nuskin", train_taps, log=lambda line: print(line, file=sys.stderr)
    )
    return out, (
        f"the demo's, trained here on {train_taps} streamed taps in "
        f"{time.monotonic() - t0:.0f} s ({missing})"
    )


# ------------------------------------------------------------------------------ graphs
def spin_in_background(node: Any) -> Callable[[], None]:
    """Spin ``node`` on its own executor thread; returns the function that stops and joins it."""
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
    """Start the nodes ``names`` of ``graph`` (``ext_sense.graphs.GRAPHS``) for ``overrides``.

    ``pythonpath``: another source tree first on the path (``--baseline``), whose graph
    description is then the one used.
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


def stop_graph(proc: subprocess.Popen[bytes]) -> None:
    """SIGINT to the runner (it forwards SIGINT to every node), then wait; kill as last resort."""
    if proc.poll() is None:
        proc.send_signal(signal.SIGINT)
    try:
        proc.wait(timeout=15.0)
    except subprocess.TimeoutExpired:
        proc.kill()
        proc.wait(timeout=5)


def watch_diagnostics(node: Any) -> dict[str, dict[str, str]]:
    """Status name -> its newest key/value pairs on ``/diagnostics``, filled as ``node`` spins."""
    from diagnostic_msgs.msg import DiagnosticArray

    from ext_sense_runtime.qos import DIAGNOSTICS_QOS

    diag: dict[str, dict[str, str]] = {}

    def on_diag(msg: DiagnosticArray) -> None:
        for st in msg.status:
            diag[st.name] = {kv.key: kv.value for kv in st.values}

    node.create_subscription(DiagnosticArray, "/diagnostics", on_diag, DIAGNOSTICS_QOS)
    return diag


def worst_case_ms() -> tuple[bytes, int]:
    """One ms of the worst case as receiver words (4 ticks of all 80 taxels), and its words."""
    from ext_sense_drivers.nuskin.wire import encode_words

    taxels = np.tile(np.arange(1, 81), 4)
    values = np.random.default_rng(0).integers(0, 1024, taxels.size)
    return encode_words(taxels, values), taxels.size


def worst_case_run(seconds: float, hot_path: str = "", bag: Path | None = None) -> dict[str, Any]:
    """80 taxels at 4 kHz for ``seconds`` as receiver words over a pty into the tap graph's
    ``nuskin_driver`` and ``contact_window`` (``bag``: ``ext-sense record`` of the packets too).

    Returns:
        ``diag`` (the graph's diagnostics after the drain), ``words_sent``, ``write_wall_s`` and
        ``cpu_percent`` per process (% of one core while streaming).
    """
    import tty

    import rclpy
    from rclpy.node import Node

    master, slave = os.openpty()
    tty.setraw(slave)
    overrides = {"sensor": "nuskin", "source": "serial", "port": os.ttyname(slave)}
    overrides |= {"monitor": "false"} | ({"hot_path": hot_path} if hot_path else {})
    graph = start_graph("tap_localization", overrides, ("nuskin_driver", "contact_window"))
    recorder = None
    if bag is not None:
        recorder = subprocess.Popen(
            [sys.executable, "-m", "ext_sense.cli", "record", str(bag), "--topics", PACKETS],
            stdout=subprocess.DEVNULL,
            stderr=subprocess.PIPE,
            start_new_session=True,
        )
    rclpy.init(args=[])
    node = Node("bench_worst_case")
    diag = watch_diagnostics(node)
    halt = spin_in_background(node)
    try:
        subscribers = 1 if recorder is None else 2  # the window node and the recorder
        end = time.monotonic() + 60.0
        while time.monotonic() < end and node.count_subscribers(PACKETS) < subscribers:
            time.sleep(0.05)
        time.sleep(2.0)  # port open
        pids = {p: process_name(p) for p in children(graph.pid)}
        if recorder is not None:
            pids[recorder.pid] = "recorder (ext-sense record)"
        chunk, words = worst_case_ms()
        start = {p: cpu_ticks(p) for p in pids}
        t0 = time.monotonic()
        for i in range(int(seconds * 1000)):
            delay = t0 + (i + 1) / 1000 - time.monotonic()
            if delay > 0:
                time.sleep(delay)
            os.write(master, chunk)
        wall = time.monotonic() - t0
        stop = {p: cpu_ticks(p) for p in pids}
        time.sleep(3.0)  # drain, then two diagnostics periods
    finally:
        halt()
        node.destroy_node()
        rclpy.try_shutdown()
        if recorder is not None:
            stop_group(recorder, 30)
        stop_graph(graph)
        os.close(master)
        os.close(slave)
    return {
        "diag": diag,
        "words_sent": words * int(seconds * 1000),
        "write_wall_s": wall,
        "cpu_percent": {pids[p]: v for p, v in cpu_percent(start, stop, wall).items() if v == v},
    }


def main() -> int:
    """A graph's process: ``run_graph`` on the named nodes of the graph in ``argv[1]``."""
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
