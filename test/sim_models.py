"""Models for system tests, trained by the one training recipe on a small simulated set, and
the graph processes those tests start and stop.

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
"""The ``ext-sense`` command of this interpreter, for the graphs the system tests start."""


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
    from ext_sense_perception.data.sources import from_sim_dataset
    from ext_sense_perception.training.recipe import train_bundle
    from ext_sense_sim.run import run_scene
    from ext_sense_sim.scene import load_scene

    data, model = root / f"{task}_data", root / f"{task}_model"
    run_scene(load_scene(scene), data, trials, seed, formats=("npz",))
    npz = as_delivered(data / "dataset.npz", data / "delivered.npz")
    ws = from_sim_dataset(npz)
    assert ws.task == task, (ws.task, task)
    train_bundle(ws, model)
    return model, npz
