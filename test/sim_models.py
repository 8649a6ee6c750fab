"""Models for system tests, trained through the CLI on a small simulated set, and the graph
processes those tests start and stop.

The set is the scene's trials as the driver delivers them (``demo.as_delivered``), as the demo
trains, so a model sees the same windows in a test as in use.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
from pathlib import Path

EXE = [sys.executable, "-m", "ext_sense.cli"]


def cli(*args: str, timeout: float = 240) -> subprocess.CompletedProcess:
    """Run ``ext-sense ARGS`` in a child process, capturing its output."""
    return subprocess.run([*EXE, *args], capture_output=True, text=True, timeout=timeout)


def stop_graph(proc: subprocess.Popen, timeout: float = 20) -> tuple[str, str]:
    """Stop a graph started with ``start_new_session=True``: SIGINT to its process group (the
    runner and every node), SIGKILL if it is not gone after ``timeout`` s.

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


def train_sim_model(
    root: Path, scene: str, task: str, trials: int, seed: int = 11
) -> tuple[Path, Path]:
    """Simulate ``trials`` of ``scene`` into ``root`` and train a NUSkin model on them.

    Returns:
        ``(model_dir, dataset.npz as delivered)``.
    """
    from ext_sense.commands.demo import as_delivered

    data, model = root / f"{task}_data", root / f"{task}_model"
    out = cli(
        "sim", "run", scene, "--out", str(data), "--trials", str(trials), "--seed", str(seed),
        "--formats", "npz",
    )  # fmt: skip
    assert out.returncode == 0, out.stderr
    npz = as_delivered(data / "dataset.npz", data / "delivered.npz")
    out = cli(
        "train", "--task", task, "--sensor", "nuskin", "--data", str(npz), "--out", str(model)
    )  # fmt: skip
    assert out.returncode == 0, out.stderr
    return model, npz
