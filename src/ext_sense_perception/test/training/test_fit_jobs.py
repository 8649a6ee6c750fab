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
from ext_sense_perception.training.fit_jobs import (
    FitCache,
    FitFailure,
    FitJob,
    FitRunner,
    fit_runner,
)
from ext_sense_perception.training.protocol import (
    assemble,
    evaluate,
    features_for,
    plan_evaluation,
)
from ext_sense_perception.training.split_fit import code_digest, code_modules

DASK = Path(sys.executable).with_name("dask")


def _evaluate_json(args: list[str], out: Path) -> dict:
    assert main(["evaluate", *args, "--k", "3", "--json", str(out), "--no-progress"]) == 0
    rec = json.loads(out.read_text())
    return {k: rec[k] for k in ("scores", "best_params", "confusion", "mean")}


def test_cache_makes_a_rerun_compute_only_what_changed(tap_npz, tmp_path, capsys):
    ws = from_sim_dataset(tap_npz)
    cache = FitCache(tmp_path / "fits")
    first = FitRunner(cache=cache)
    a = evaluate(ws, features_for(ws, "fft"), "svm_rbf", k=3, executor=first)
    assert (first.done, first.cached) == (3, 0)
    again = FitRunner(cache=cache)
    b = evaluate(ws, features_for(ws, "fft"), "svm_rbf", k=3, executor=again)
    assert (again.done, again.cached) == (3, 3)
    np.testing.assert_array_equal(a.y_pred, b.y_pred)
    other = FitRunner(cache=cache)  # another model: its fits only
    evaluate(ws, features_for(ws, "fft"), "svm_linear", k=3, executor=other)
    evaluate(ws, features_for(ws, "fft"), "svm_rbf", k=3, executor=other)
    assert (other.done, other.cached) == (6, 3)


def test_a_failed_fit_keeps_the_others_and_names_the_failure(tmp_path):
    cache = FitCache(tmp_path / "fits")
    ex = FitRunner(cache=cache)

    def fit(task: int) -> int:
        if task == 2:
            raise ValueError("bad split")
        return task * 10

    with pytest.raises(PerceptionError, match=r"1 of 3 fits failed .* ValueError: bad split"):
        ex.map(fit, [1, 2, 3], ["k1", "k2", "k3"])
    assert (cache.get("k1"), cache.get("k2"), cache.get("k3")) == (10, None, 30)
    assert FitRunner(cache=cache).map(lambda t: t, [1, 3], ["k1", "k3"]) == [10, 30]


def test_progress_into_a_log_writes_whole_lines_not_carriage_returns(tmp_path, capsys):
    """A log file (stderr not a terminal, as in CI or ``nohup``) gets readable lines: the first
    and the last (within ``LOG_EVERY_S`` of each other, nothing between)."""
    cache = FitCache(tmp_path / "fits")
    cache.put("k1", 10)
    FitRunner(cache=cache, progress=True).map(lambda t: t, [1, 2, 3], ["k1", "k2", "k3"])
    lines = [line.rstrip() for line in capsys.readouterr().err.splitlines() if line.strip()]
    assert [line.split(", about")[0] for line in lines] == [
        "fits: 1 of 3 done (1 cached), 0 failed",
        "fits: 3 of 3 done (1 cached), 0 failed",
    ]
    assert "\r" not in "".join(lines)


def test_cluster_options_are_checked():
    with pytest.raises(PerceptionError, match="not both"), fit_runner("tcp://x:1", 2):
        pass
    with (
        pytest.raises(PerceptionError, match="'--workers' option must be >= 1"),
        fit_runner(None, 0),
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


POINTS = [("fft", "svm_rbf"), ("fft", "svm_linear"), ("baseline", "svm_rbf")]


def _same(a, b) -> None:
    np.testing.assert_array_equal(a.scores, b.scores)
    np.testing.assert_array_equal(a.y_pred, b.y_pred)
    assert a.best_params == b.best_params


def _all_at_once(ws, executor: FitRunner) -> list:
    plans = [plan_evaluation(ws, features_for(ws, f), m, k=3) for f, m in POINTS]
    outcomes = executor.run_jobs([p.job() for p in plans])
    return [assemble(p, r) for p, r in zip(plans, outcomes, strict=True)]


def test_points_submitted_together_equal_points_one_by_one(tap_npz):
    ws = from_sim_dataset(tap_npz)
    one_by_one = [evaluate(ws, features_for(ws, f), m, k=3, progress=False) for f, m in POINTS]
    ex = FitRunner()
    for a, b in zip(one_by_one, _all_at_once(ws, ex), strict=True):
        _same(a, b)
    assert ex.done == 9


@pytest.mark.slow  # starts a local cluster of worker processes
def test_points_submitted_together_on_a_cluster_equal_points_one_by_one(tap_npz):
    ws = from_sim_dataset(tap_npz)
    one_by_one = [evaluate(ws, features_for(ws, f), m, k=3, progress=False) for f, m in POINTS]
    with fit_runner(workers=2) as ex:
        together = _all_at_once(ws, ex)
    for a, b in zip(one_by_one, together, strict=True):
        _same(a, b)


def test_a_failed_fit_in_a_multi_point_run_stays_with_its_point():
    def fit(task: int, offset: int) -> int:
        if task == 2:
            raise ValueError("bad split")
        return task + offset

    jobs = [
        FitJob(fit, [1, 2], ["a1", "a2"], {"offset": 10}),
        FitJob(fit, [3], ["b3"], {"offset": 0}),
    ]
    first, second = FitRunner().run_jobs(jobs)
    assert first[0] == 11
    assert isinstance(first[1], FitFailure)
    assert second == [3]


def test_a_job_with_a_store_keeps_its_fits_in_that_subdirectory(tmp_path):
    calls: list[int] = []

    def fit(task: int) -> int:
        calls.append(task)
        return 2 * task

    cache = FitCache(tmp_path / "fits")
    jobs = [FitJob(fit, [1], ["k1"], {}), FitJob(fit, [2], ["k2"], {}, "deployed")]
    assert FitRunner(cache=cache).run_jobs(jobs) == [[2], [4]]
    assert len(list((tmp_path / "fits").rglob("output.pkl"))) == 2
    assert len(list((tmp_path / "fits" / "deployed").rglob("output.pkl"))) == 1
    assert "k1" in cache
    assert "k2" not in cache  # the main store holds the split fits only
    assert FitRunner(cache=cache).run_jobs(jobs) == [[2], [4]]
    assert calls == [1, 2]  # the rerun found both


def _write_package(root: Path, helper: str = "SCALE = 1.0", other: str = "X = 1") -> None:
    pkg = root / "es18pkg"
    pkg.mkdir(exist_ok=True)
    (pkg / "__init__.py").write_text("")
    (pkg / "helper.py").write_text(helper + "\n")
    (pkg / "other.py").write_text(other + "\n")  # imported by nothing the model runs
    (pkg / "model.py").write_text(
        "from sklearn.base import BaseEstimator\n"
        "from es18pkg.helper import SCALE\n\n\n"
        "class Scaled(BaseEstimator):\n"
        "    def __init__(self, c=1.0):\n"
        "        self.c = c\n"
    )


def test_code_digest_covers_the_model_modules_only(tmp_path, monkeypatch):
    from sklearn.pipeline import Pipeline
    from sklearn.preprocessing import StandardScaler

    _write_package(tmp_path)
    monkeypatch.syspath_prepend(str(tmp_path))
    from es18pkg.model import Scaled

    pipe = Pipeline([("scale", StandardScaler()), ("model", Scaled())])
    modules, versions = code_modules(pipe, ("es18pkg",))
    assert modules == ["es18pkg.helper", "es18pkg.model"]
    assert any(v.startswith("sklearn scikit-learn==") for v in versions)
    before = code_digest(pipe, ("es18pkg",))
    _write_package(tmp_path, other="X = 2")  # an unrelated module of the same package
    assert code_digest(pipe, ("es18pkg",)) == before
    _write_package(tmp_path, helper="SCALE = 2.0")  # a module the model imports
    changed = code_digest(pipe, ("es18pkg",))
    assert changed != before
    model = tmp_path / "es18pkg" / "model.py"
    model.write_text('"""The model."""\n' + model.read_text() + "# a comment\n")
    assert code_digest(pipe, ("es18pkg",)) == changed  # docstrings and comments: same code
    model.write_text(model.read_text() + "LIMIT = 3\n")
    assert code_digest(pipe, ("es18pkg",)) not in (before, changed)


def test_the_project_code_hash_of_an_svm_leaves_out_other_models_and_precomputed_features(
    tap_npz,
):
    ws = from_sim_dataset(tap_npz)
    svm = plan_evaluation(ws, features_for(ws, "fft"), "svm_rbf", k=2).tasks[0].pipe
    assert code_modules(svm)[0] == []  # scaler + SVR: scikit-learn's, by its version
    gru = "ext_sense_perception.training.gru"
    auto = plan_evaluation(ws, features_for(ws, "autoencoder"), "svm_rbf", k=2).tasks[0].pipe
    modules = code_modules(auto)[0]
    assert "ext_sense_perception.features.transformer" in modules
    assert gru not in modules


@pytest.mark.slow  # starts a local cluster of worker processes
def test_a_fit_lost_with_its_worker_is_run_again_with_its_data_sent_again(tmp_path):
    """Two workers (on a cluster of one, joblib runs the fits in this process)."""

    def fit_that_kills_its_worker_once(task: int, marker: str, data: np.ndarray) -> float:
        """Its first call for task 1 ends its worker process, as a killed or hung worker ends
        on a cluster: the worker's copy of the scattered data goes with it. (Defined here, so
        the workers get it by value: pytest imports this module under a name they lack.)"""
        import os
        from pathlib import Path

        if task == 1 and not os.path.exists(marker):
            Path(marker).touch()
            os._exit(1)
        return float(data.sum()) + task

    data = np.arange(1000.0)
    marker = str(tmp_path / "killed")
    job = FitJob(fit_that_kills_its_worker_once, [0, 1, 2], ["a", "b", "c"], {"data": data})
    job.data["marker"] = marker
    with fit_runner(workers=2) as ex:
        [results] = ex.run_jobs([job])
    assert Path(marker).exists()  # the worker was killed
    assert results == [data.sum() + t for t in (0, 1, 2)]
    assert ex.failed == 0
    assert ex.resent >= 1
