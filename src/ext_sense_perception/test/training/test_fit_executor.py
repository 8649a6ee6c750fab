"""Protocol fits here, on a local Dask cluster and on a TCP cluster.

The three give the same results; a cache of finished fits makes reruns incremental.
"""

from __future__ import annotations

import json
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from ext_sense.cli import main
from ext_sense_perception.data.sources import from_sim_dataset
from ext_sense_perception.errors import PerceptionError
from ext_sense_perception.training.fit_executor import FitCache, FitExecutor, fit_executor
from ext_sense_perception.training.protocol import evaluate, features_for

DASK = Path(sys.executable).with_name("dask")


def _evaluate_json(args: list[str], out: Path) -> dict:
    assert main(["evaluate", *args, "--k", "3", "--json", str(out), "--no-progress"]) == 0
    rec = json.loads(out.read_text())
    return {k: rec[k] for k in ("scores", "best_params", "confusion", "mean")}


def test_cache_makes_a_rerun_compute_only_what_changed(tap_npz, tmp_path, capsys):
    ws = from_sim_dataset(tap_npz)
    cache = FitCache(tmp_path / "fits")
    first = FitExecutor(cache=cache)
    a = evaluate(ws, features_for(ws, "fft"), "svm_rbf", k=3, executor=first)
    assert (first.progress.done, first.progress.cached) == (3, 0)
    again = FitExecutor(cache=cache)
    b = evaluate(ws, features_for(ws, "fft"), "svm_rbf", k=3, executor=again)
    assert (again.progress.done, again.progress.cached) == (3, 3)
    np.testing.assert_array_equal(a.y_pred, b.y_pred)
    other = FitExecutor(cache=cache)  # another model: its fits only
    evaluate(ws, features_for(ws, "fft"), "svm_linear", k=3, executor=other)
    evaluate(ws, features_for(ws, "fft"), "svm_rbf", k=3, executor=other)
    assert (other.progress.done, other.progress.cached) == (6, 3)


def test_a_failed_fit_keeps_the_others_and_names_the_failure(tmp_path):
    cache = FitCache(tmp_path / "fits")
    ex = FitExecutor(cache=cache)

    def fit(task: int) -> int:
        if task == 2:
            raise ValueError("bad split")
        return task * 10

    with pytest.raises(PerceptionError, match=r"1 of 3 fits failed .* ValueError: bad split"):
        ex.map(fit, [1, 2, 3], ["k1", "k2", "k3"])
    assert (cache.get("k1"), cache.get("k2"), cache.get("k3")) == (10, None, 30)
    assert FitExecutor(cache=cache).map(lambda t: t, [1, 3], ["k1", "k3"]) == [10, 30]


def test_cluster_options_are_checked():
    with pytest.raises(PerceptionError, match="not both"), fit_executor("tcp://x:1", 2):
        pass
    with (
        pytest.raises(PerceptionError, match="'--workers' option must be >= 1"),
        fit_executor(None, 0),
    ):
        pass


@pytest.mark.slow  # starts a local cluster and a TCP cluster of worker processes
def test_single_process_equals_local_cluster_equals_tcp_cluster(tap_npz, tmp_path):
    data = ["--data", str(tap_npz), "--features", "fft", "--model", "svm_rbf"]
    alone = _evaluate_json(data, tmp_path / "alone.json")
    local = _evaluate_json([*data, "--workers", "2"], tmp_path / "local.json")
    sched_file = tmp_path / "scheduler.json"
    procs = [
        subprocess.Popen(
            [
                str(DASK),
                "scheduler",
                "--scheduler-file",
                str(sched_file),
                "--port",
                "0",
                "--no-dashboard",
            ],
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
        )
    ]
    try:
        deadline = time.monotonic() + 60
        while not sched_file.exists() and time.monotonic() < deadline:
            time.sleep(0.2)
        address = json.loads(sched_file.read_text())["address"]
        for _ in range(2):
            procs.append(
                subprocess.Popen(
                    [str(DASK), "worker", address, "--nthreads", "1", "--no-dashboard"],
                    stdout=subprocess.DEVNULL,
                    stderr=subprocess.DEVNULL,
                )
            )
        from distributed import Client

        with Client(address, timeout="30s") as client:
            client.wait_for_workers(2, timeout=60)
        tcp = _evaluate_json([*data, "--scheduler", address], tmp_path / "tcp.json")
    finally:
        for p in procs:
            p.terminate()
        for p in procs:
            p.wait(timeout=30)
    assert alone == local == tcp
