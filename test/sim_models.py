"""Models for system tests, trained by the one training recipe on a small simulated set, and
the graph processes those tests start and stop.

The set is the scene's trials as the driver delivers them (``default_models.as_delivered``), as
the demo trains, so a model sees the same windows in a test as in use.
"""

from __future__ import annotations

import os
import re
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

from ext_sense.cli import NOT_STARTED

EXE = [sys.executable, "-m", "ext_sense.cli"]
"""The ``ext-sense`` command of this interpreter, for the graphs the system tests start."""

CRASH_MARKERS = ("Traceback", "terminate called", "Fatal Python error", "Aborted")
"""Output of a process that did not stop cleanly (a Python traceback, a C++ abort)."""

STACK_LINES = 30
"""Output lines kept after each crash marker: the stack that follows it."""

EXIT_CODES = re.compile(r"^\[run\] exit codes: (.*)$", re.MULTILINE)


def cli(*args: str, timeout: float = 240) -> subprocess.CompletedProcess:
    """Run ``ext-sense ARGS`` in a child process, capturing its output."""
    return subprocess.run([*EXE, *args], capture_output=True, text=True, timeout=timeout)


def spawn(*args: str) -> subprocess.Popen:
    """Start ``ext-sense ARGS`` in a session of its own (its process group: a graph's runner
    and nodes), output captured as text; stop a graph with :func:`stop_graph`."""
    return subprocess.Popen(
        [*EXE, *args],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        start_new_session=True,
    )


def stop_graph(proc: subprocess.Popen, timeout: float = 20) -> tuple[str, str]:
    """Stop a graph started with ``start_new_session=True``: SIGINT to its process group (the
    runner and every node), SIGKILL if it is not gone after ``timeout`` s.

    Every node ends with exit code 0 on that SIGINT, without abort or traceback:
    :func:`stop_problems` lists what was not clean, for the caller to assert on.

    Returns:
        ``(stdout, stderr)`` of the runner.
    """
    if proc.poll() is None:
        os.killpg(proc.pid, signal.SIGINT)
    try:
        return proc.communicate(timeout=timeout)
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, signal.SIGKILL)
        return proc.communicate()


def finish_graph(
    proc: subprocess.Popen, timeout: float, what: str = "the graph"
) -> tuple[str, str]:
    """Wait for a graph started by :func:`spawn` to end by itself; ``(stdout, stderr)``.

    Not ended after ``timeout`` s: it is stopped (:func:`stop_graph`) and the test fails with
    its output.
    """
    import pytest

    try:
        return proc.communicate(timeout=timeout)
    except subprocess.TimeoutExpired:
        stdout, stderr = stop_graph(proc, timeout=10)
        pytest.fail(f"{what} did not finish in {timeout:g} s:\n{stdout}\n{stderr[-3000:]}")


def child_exit_codes(stderr: str) -> dict[str, int]:
    """The node exit codes ``ext-sense run`` reported when the graph stopped (``{}``: none)."""
    found = EXIT_CODES.findall(stderr)
    if not found:
        return {}
    pairs = (item.split("=", 1) for item in found[-1].split())
    return {name: int(code) for name, code in pairs}


def stop_problems(proc: subprocess.Popen, stdout: str, stderr: str) -> list[str]:
    """What was not clean about a graph's end: the runner's exit code, any node's exit code
    (as the runner reported them), and every output line of a crash (:data:`CRASH_MARKERS`)
    with the :data:`STACK_LINES` after it (a traceback's or faulthandler's stack).

    Returns:
        One line per problem; empty when the runner and every node exited with 0.
    """
    problems = []
    if proc.returncode != 0:
        problems.append(f"runner exited with {proc.returncode}")
    codes = child_exit_codes(stderr)
    if not codes and NOT_STARTED not in stderr:
        problems.append("the runner reported no exit codes of its nodes")
    problems += [f"{name} exited with {code}" for name, code in codes.items() if code != 0]
    lines = (stdout + "\n" + stderr).splitlines()
    kept_until = 0  # lines up to here are already shown as a stack
    for i, line in enumerate(lines):
        if i >= kept_until and any(marker in line for marker in CRASH_MARKERS):
            problems.append(f"output: {line.strip()[:200]}")
            # the stack a traceback or faulthandler printed after it, to find the crash by
            kept_until = i + 1 + STACK_LINES
            problems += [f"  {after.rstrip()[:200]}" for after in lines[i + 1 : kept_until]]
    return problems


_TRAINED: dict[tuple[str, str, int, int], tuple[Path, Path]] = {}
"""Models this test process trained, by their inputs: training is deterministic, so a graph test
asking for the same model again gets the one already on disk (the tests only read them)."""


def train_sim_model(
    root: Path, scene: str, task: str, trials: int, seed: int = 11
) -> tuple[Path, Path]:
    """Simulate ``trials`` of ``scene`` into ``root`` and train a NUSkin model on them.

    A model of the same inputs trained before in this process is returned instead (it lives in
    that earlier test's directory, which pytest keeps for the session).

    Returns:
        ``(model_dir, dataset.npz as delivered)``.
    """
    key = (scene, task, trials, seed)
    earlier = _TRAINED.get(key)
    if earlier is not None and (earlier[0] / "model_card.json").is_file() and earlier[1].is_file():
        return earlier
    _TRAINED[key] = _train_sim_model(root, scene, task, trials, seed)
    return _TRAINED[key]


def _train_sim_model(
    root: Path, scene: str, task: str, trials: int, seed: int
) -> tuple[Path, Path]:
    from ext_sense_perception.data.sources import from_sim_dataset
    from ext_sense_perception.training.recipe import train_bundle
    from ext_sense_sim.default_models import as_delivered
    from ext_sense_sim.run import run_scene
    from ext_sense_sim.scene import load_scene

    data, model = root / f"{task}_data", root / f"{task}_model"
    run_scene(load_scene(scene), data, trials, seed, formats=("npz",))
    npz = as_delivered(data / "dataset.npz", data / "delivered.npz")
    ws = from_sim_dataset(npz)
    assert ws.task == task, (ws.task, task)
    train_bundle(ws, model)
    return model, npz


def write_card(directory: Path, task: str = "tap_localization", sensor: str = "nuskin") -> Path:
    """A bundle directory holding only a valid model card (for the model lookup, not inference)."""
    from ext_sense_perception.online.model_card import ModelCard
    from ext_sense_perception.online.model_input import Geometry
    from ext_sense_perception.profiles import profile_for

    directory.mkdir(parents=True, exist_ok=True)
    profile = profile_for(task)
    period = profile.period_ns(sensor)
    n_samples = (profile.pre_ns + profile.post_ns) // period  # the profile's whole window
    ModelCard(
        task=task,
        sensor=sensor,
        profile=profile,
        window=Geometry(80 if sensor == "nuskin" else 1, n_samples, period, profile.pre_ns, sensor),
        features="baseline",
        feature_params={},
        model="card-only",
        best_params={},
        rate_hz=4000.0,
        class_names=() if task == "tap_localization" else ("a", "b"),
        metrics={},
        n_train=0,
        data="",
        data_hash="",
    ).write(directory)
    return directory


STOP_LIMIT_S = 8.0
"""Longest time from the first signal until the whole process group is gone: well inside
launch's grace period (SIGTERM after 5 s, SIGKILL 5 s later) once the runner's own 5 s SIGKILL
fallback is counted (it must never be needed: a killed node reports -9)."""


class Command:
    """``ext-sense ARGS`` in its own process group, its output read as it comes."""

    def __init__(self, *args: str, sigint_ignored: bool = False) -> None:
        # SIGINT ignored as a shell without job control starts a background command
        ignoring = ["sh", "-c", 'trap "" INT; exec "$@"', "sh"] if sigint_ignored else []
        self.proc = subprocess.Popen(
            [*ignoring, *EXE, *args],
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
            start_new_session=True,
        )
        self.out: list[str] = []
        self.err: list[str] = []
        self.readers = [
            threading.Thread(target=self._read, args=(s, lines), daemon=True)
            for s, lines in ((self.proc.stdout, self.out), (self.proc.stderr, self.err))
        ]
        for r in self.readers:
            r.start()

    @staticmethod
    def _read(stream, lines: list[str]) -> None:
        for line in stream:
            lines.append(line)

    def printed(self, text: str) -> bool:
        """Whether a line of its standard output holds ``text``."""
        return any(text in line for line in self.out)

    def output(self) -> str:
        """Everything it printed so far, standard output then standard error."""
        return "".join(self.out) + "".join(self.err)

    def interrupt(self, timeout: float = 20.0) -> int:
        """SIGINT to the process group (as Ctrl-C in a terminal), SIGKILL after ``timeout`` s;
        its exit code."""
        if self.proc.poll() is None:
            os.killpg(self.proc.pid, signal.SIGINT)
        try:
            self.proc.wait(timeout=timeout)
        except subprocess.TimeoutExpired:
            os.killpg(self.proc.pid, signal.SIGKILL)
            self.proc.wait()
        for r in self.readers:
            r.join(timeout=5)
        return self.proc.returncode


class Graph(Command):
    """``ext-sense run GRAPH`` in its own process group, its output read as it comes."""

    def __init__(
        self, *args: str, graph: str = "tap_localization", sigint_ignored: bool = False
    ) -> None:
        super().__init__("run", graph, *args, sigint_ignored=sigint_ignored)
        self.left_alive = ""  # ``ps`` of the processes still alive when ``stop`` gave up

    def wait_for_tap(self, timeout: float) -> bool:
        """Whether the monitor printed an estimate (every node up and working) in time."""
        end = time.monotonic() + timeout
        while time.monotonic() < end and self.proc.poll() is None:
            if any(x.startswith("tap ") for x in self.out):
                return True
            time.sleep(0.05)
        return False

    def group_alive(self) -> bool:
        try:
            os.killpg(self.proc.pid, 0)
        except ProcessLookupError:
            return False
        return True

    def stop(self, signals: list[tuple[float, signal.Signals]]) -> float:
        """Send ``signals`` to the process group; returns the seconds until the group is gone
        (``inf`` if it was not gone after :data:`STOP_LIMIT_S`, then it is killed)."""
        start = time.monotonic()
        for delay, signum in signals:
            time.sleep(delay)
            if self.group_alive():
                os.killpg(self.proc.pid, signum)
        while self.group_alive() and time.monotonic() - start < STOP_LIMIT_S:
            self.proc.poll()  # reap the runner; its children are its to reap
            time.sleep(0.02)
        took = time.monotonic() - start
        if self.group_alive():
            self.left_alive = subprocess.run(  # what outlived the limit, for the failure message
                ["ps", "-o", "pid,ppid,stat,etime,wchan:20,args", "-s", str(self.proc.pid)],
                capture_output=True,
                text=True,
            ).stdout
            os.killpg(self.proc.pid, signal.SIGKILL)
            took = float("inf")
        self.proc.wait(timeout=10)
        for r in self.readers:
            r.join(timeout=5)
        return took

    def node_pid(self, name: str) -> int:
        """The process id of the graph's node ``name`` (a child of the runner).

        Raises:
            LookupError: No such node process (not started, or gone).
        """
        marker = f'"name": "{name}"'
        for entry in Path("/proc").iterdir():
            if not entry.name.isdigit():
                continue
            try:
                stat = (entry / "stat").read_text()
                cmdline = (entry / "cmdline").read_bytes().decode(errors="replace")
            except OSError:
                continue
            ppid = int(stat.rsplit(")", 1)[1].split()[1])
            if ppid == self.proc.pid and "ext_sense.runner" in cmdline and marker in cmdline:
                return int(entry.name)
        raise LookupError(f"no process of node {name!r} under runner {self.proc.pid}")
