"""The three tasks end to end: emulated devices (pty and CAN) and bag replay, with real models.

Models are trained once per session on small simulated sets (as the demo does, on events as
the driver delivers them), so these tests check that the graph works end to end (every trial
gets a final estimate matched to it, the summary line is printed, the graph stops by itself),
not how accurate a model trained on a few dozen trials is: docs/benchmarks.md records accuracy.
"""

from __future__ import annotations

import os
import re
import subprocess
from pathlib import Path

import numpy as np
import pytest
from sim_models import cli as _cli
from sim_models import finish_graph, spawn, train_sim_model

pytestmark = [pytest.mark.ros, pytest.mark.slow, pytest.mark.timeout(400)]

SUMMARY_TAP = re.compile(
    r"^summary: taps=(\d+) mae_cm=([\d.]+|nan) compute_p50_ms=([\d.]+) compute_p99_ms=([\d.]+)$"
)
SUMMARY_CLASS = re.compile(
    r"^summary: trials=(\d+) accuracy=([\d.]+|nan) compute_p50_ms=([\d.]+) compute_p99_ms=([\d.]+)$"
)
TRAIN = {
    # task: (scene, training trials, graph name)
    "tap_localization": ("tap_rod30_nuskin", 40, "tap_localization"),
    "handover_stability": ("handover_rod_nuskin", 20, "handover"),
    "food_identification": ("food_fork_nuskin", 14, "food_identification"),
}


@pytest.fixture(scope="session")
def models(tmp_path_factory):
    """Each task's model, trained once (``train_sim_model`` keeps what it trained):
    {task: (model_dir, dataset.npz as delivered)}."""
    root = tmp_path_factory.mktemp("e2e_models")

    def get(task: str) -> tuple[Path, Path]:
        scene, trials, _ = TRAIN[task]
        return train_sim_model(root, scene, task, trials)

    return get


def _run_graph(graph: str, model: Path, trials: int, *extra: str, timeout: float = 120):
    """Run a graph with ``ext-sense run``; on a timeout its whole process group is stopped."""
    proc = spawn(
        "run",
        graph,
        f"trials:={trials}",
        f"model:={model}",
        "seed:=5",
        f"port:=/tmp/ext_sense_e2e_{os.getpid()}_{graph}.pty",
        *extra,
    )
    stdout, stderr = finish_graph(proc, timeout, graph)
    out = subprocess.CompletedProcess(proc.args, proc.returncode, stdout, stderr)
    lines = [x for x in stdout.splitlines() if x.strip()]
    return out, lines


def _check_summary(out, lines, pattern, trials, at_least=None):
    assert out.returncode == 0, out.stderr[-3000:]
    assert lines, out.stderr[-3000:]
    match = pattern.match(lines[-1])
    assert match, lines[-5:]
    scored = int(match.group(1))
    assert scored >= (trials - 1 if at_least is None else at_least), lines
    # p50 compute latency in ms: sane (no unit slip), not a target (106 ms once for the handover
    # on a slow 2-core machine running the whole suite; docs/benchmarks.md has the targets)
    assert float(match.group(3)) < 500.0
    return match


def test_tap_localization_over_pty_with_a_process_per_node(models):
    """``hot_path:=processes``: driver, window and inference nodes each in a process."""
    model, _ = models("tap_localization")
    out, lines = _run_graph("tap_localization", model, 4, "hot_path:=processes")
    _check_summary(out, lines, SUMMARY_TAP, 4)
    assert sum(x.startswith("tap ") for x in lines) >= 3


def test_tap_localization_over_can(models):
    model, _ = models("tap_localization")
    # python-can's virtual bus joins buses of one process only: the graph runs in one process
    out, lines = _run_graph(
        "tap_localization", model, 3, f"can_channel:=e2e{os.getpid()}", "--in-process"
    )
    _check_summary(out, lines, SUMMARY_TAP, 3)


def test_tap_localization_with_the_hot_path_in_one_process(models):
    """The default ``hot_path:=one_process``: driver, window and inference nodes in one
    node_group process."""
    model, _ = models("tap_localization")
    out, lines = _run_graph("tap_localization", model, 4)
    _check_summary(out, lines, SUMMARY_TAP, 4)
    assert "started hot_path: nuskin_driver contact_window contact_inference in one process" in (
        out.stderr
    )
    assert "[run] exit codes: sim_device=0 hot_path=0 estimate_monitor=0" in out.stderr
    # no middleware hop between the three nodes
    for topic in ("/extsense/nuskin/packets", "/extsense/contact_window"):
        assert f"{topic}: messages of this process handed over in process" in out.stderr


def test_handover_over_pty(models):
    model, _ = models("handover_stability")
    out, lines = _run_graph("handover", model, 3)
    # the emulated handover device streamed only some trials under load in measurement
    _check_summary(out, lines, SUMMARY_CLASS, 3, at_least=1)


def test_food_identification_over_pty(models):
    model, _ = models("food_identification")
    out, lines = _run_graph("food_identification", model, 2, timeout=150)
    _check_summary(out, lines, SUMMARY_CLASS, 2)


@pytest.mark.parametrize("task", sorted(TRAIN))
def test_bag_replay_offline_every_task(models, task, tmp_path):
    from ext_sense_sim.output.bag import write_bag

    model, npz = models(task)
    bag = tmp_path / "bag"
    period = 12 * 10**9 if task == "food_identification" else 10**9
    write_bag(np.load(npz), bag, trial_period_ns=period, trials=6)
    runs = []
    for name in ("a.json", "b.json"):
        out = _cli(
            "replay", str(bag), "--offline", "--model", str(model), "--json", str(tmp_path / name)
        )
        assert out.returncode == 0, out.stderr
        runs.append(out.stdout.strip().splitlines())
    pattern = SUMMARY_TAP if task == "tap_localization" else SUMMARY_CLASS
    match = pattern.match(runs[0][-1])
    assert match, runs[0][-5:]
    assert int(match.group(1)) == 6
    # deterministic: same estimates (latency aside) in both runs
    import json

    strip = lambda path: [  # noqa: E731
        {k: v for k, v in e.items() if k != "compute_latency_ns"}
        for e in json.loads(path.read_text())
    ]
    assert strip(tmp_path / "a.json") == strip(tmp_path / "b.json")


def test_tap_bag_replay_through_the_graph(models, tmp_path):
    from ext_sense_sim.output.bag import write_bag

    model, npz = models("tap_localization")
    bag = tmp_path / "bag"
    write_bag(np.load(npz), bag, trial_period_ns=10**9, trials=4)
    out, lines = _run_graph("tap_localization", model, 4, "source:=bag", f"bag:={bag}")
    _check_summary(out, lines, SUMMARY_TAP, 4)
