"""`ext-sense report`: choosing features, models and the GRU row; the taxel-selection section."""

from __future__ import annotations

import json
import re

import pytest

from ext_sense.cli import main as ext_sense
from ext_sense_perception.errors import PerceptionError
from ext_sense_perception.reporting.report import build_report
from ext_sense_perception.reporting.runner import check_choices
from ext_sense_perception.training import fit as fit_module


def test_check_choices_canonicalises_and_keeps_order():
    feats, models = check_choices(["FFT", "raw", "fft"], ["svm_rbf", "svm_linear", "svm_rbf"])
    assert feats == ("fft", "baseline")
    assert models == ("svm_rbf", "svm_linear")
    assert check_choices(None, None) == (None, None)


@pytest.mark.parametrize(
    ("features", "models", "match"),
    [
        (["fft", "wavelet"], None, r"'features' parameter must be one of .*'wavelet'"),
        ([], None, r"'features' parameter must name at least one"),
        (None, ["svm_rbf", "xgboost"], r"'models' parameter must be among .*'xgboost'"),
        (None, ["gru"], r"GRU has its own row.*'gru'"),
        (None, [" "], r"'models' parameter must name at least one"),
    ],
)
def test_check_choices_rejects_unknown_names(features, models, match):
    with pytest.raises(PerceptionError, match=match):
        check_choices(features, models)


def test_cli_report_unknown_model_fails_before_any_work(tmp_path, capsys, make_tap_dataset):
    data = make_tap_dataset(tmp_path / "small.npz", n=20, seed=3)
    out = tmp_path / "rep"
    rc = ext_sense(
        ["report", "--data", str(data), "--out", str(out), "--models", "svm_rbf,boosted"]
    )
    assert rc == 2
    assert "'boosted'" in capsys.readouterr().err
    assert not out.exists()


@pytest.mark.slow  # a report run
def test_cli_report_runs_only_the_chosen_features_and_models(tmp_path, make_tap_dataset):
    data = make_tap_dataset(tmp_path / "small.npz", n=20, seed=3)
    out = tmp_path / "rep"
    rc = ext_sense(
        [
            "report",
            "--data",
            str(data),
            "--out",
            str(out),
            "--quick",
            "--k",
            "2",
            "--features",
            "fft",
            "--models",
            "svm_linear",
            "--no-gru",
            "--no-latency",
            "--no-taxels",
        ]
    )
    assert rc == 0
    text = (out / "report.md").read_text()
    assert "Decision latency" not in text
    assert "Two fingers" not in text
    assert "Sampling rate" in text
    table = text.split("### Features and models")[1].split("###")[0]
    rows = [line for line in table.splitlines() if line.startswith("| ") and "---" not in line]
    assert [r.split("|")[1:3] for r in rows[1:]] == [[" fft ", " svm_linear "]]
    assert "| baseline | gru |" not in text


@pytest.mark.slow  # a report run (about 6 s)
def test_report_taxel_section_has_both_models_and_a_training_chosen_taxel(
    tmp_path, make_tap_dataset
):
    data = make_tap_dataset(tmp_path / "small.npz", n=20, seed=3)
    md = build_report([data], tmp_path / "rep", k=2, quick=True, gru=False, models=["svm_rbf"])
    text = md.read_text()
    section = text.split("### Two fingers, one finger, one taxel")[1]
    header = next(line for line in section.splitlines() if line.startswith("| taxels |"))
    assert header == "| taxels | fft + svm_rbf (default) | fft + svm_linear |"
    for label in ("both fingers (80)", "one finger (1-40)", "one finger (41-80)"):
        row = next(line for line in section.splitlines() if line.startswith(f"| {label} |"))
        assert row.count(" cm") == 2
    taxel_row = next(line for line in section.splitlines() if "one taxel, chosen" in line)
    candidates = {int(v) for v in re.search(r"most active \(([\d, ]+)\)", taxel_row)[1].split(",")}
    assert len(candidates) == 2  # quick: two candidates
    chosen = re.search(r"Taxel chosen in each split: (.*)\.", section)[1]
    for part in chosen.split("; "):
        ids = {int(v) for v in part.split(": ")[1].split(", ")}
        assert ids <= candidates
    # each distinct point runs once: the default model on the full window is shared by the
    # table, the full-window decision-latency row, both fingers and the rod section
    records = json.loads((tmp_path / "rep" / "report.json").read_text())
    by_point: dict[str, set] = {}
    for r in records:
        config = (r["data"], r["features"], r["model"], json.dumps([r["params"], r["grid"]]))
        by_point.setdefault(r["point"], set()).add(config)
    assert all(len(configs) == 1 for configs in by_point.values())  # one point, one config
    table = next(r for r in records if r["study"] == "models" and r["features"] == "fft")
    shared = [r for r in records if r["point"] == table["point"]]
    assert [(r["study"], r["post_ms"], r["channels"]) for r in shared] == [
        ("models", 250.0, "all"),
        ("decision_latency", 250.0, "all"),
        ("taxels", 250.0, "all"),
        ("rod_length", 250.0, "all"),
    ]
    assert len({json.dumps(r["scores"]) for r in shared}) == 1


def test_pareto_front_keeps_the_points_nothing_beats():
    from ext_sense_perception.reporting.scores import pareto_front

    xs, errs = [1.0, 2.0, 3.0, 2.0, 4.0], [5.0, 3.0, 4.0, 3.5, 1.0]
    assert pareto_front(xs, errs, lower=True) == [0, 1, 4]
    accs = [0.5, 0.7, 0.6, 0.7, 0.9]
    assert pareto_front(xs, accs, lower=False) == [0, 1, 3, 4]  # 1 and 3 tie
    assert pareto_front([1.0, 1.0], [2.0, 2.0], lower=True) == [0, 1]  # ties both stay


def test_full_refuses_a_reduced_report(tmp_path, capsys, make_tap_dataset):
    data = make_tap_dataset(tmp_path / "small.npz", n=20, seed=3)
    args = ["report", "--data", str(data), "--out", str(tmp_path / "r"), "--full", "--quick"]
    assert ext_sense(args) == 2
    assert "'--full' report has every section" in capsys.readouterr().err


@pytest.mark.slow  # two small report runs
def test_an_interrupted_report_resumes_from_its_cached_fits(
    tmp_path, make_tap_dataset, capsys, monkeypatch
):
    data = make_tap_dataset(tmp_path / "small.npz", n=24, seed=3)
    out = tmp_path / "rep"
    args = ["report", "--data", str(data), "--out", str(out), "--k", "2", "--features", "fft"]
    args += ["--models", "svm_rbf", "--no-gru", "--no-latency", "--no-taxels"]
    assert ext_sense(args) == 0
    first = json.loads((out / "report.json").read_text())
    n_fits = sum(1 for _ in (out / "fits").rglob("*.pkl"))
    assert n_fits >= 2
    capsys.readouterr()

    def no_training(*_a, **_k):
        raise AssertionError("a deployed model was trained again")

    # the deployed model of the ONNX latency column comes from the cache too (it was trained
    # again in the report's process by every rerun, about 10 minutes per tap data set)
    monkeypatch.setattr(fit_module, "GridSearchCV", no_training)
    assert ext_sense(args) == 0
    err = capsys.readouterr().err
    assert f"{n_fits} of {n_fits} done ({n_fits} cached)" in err  # nothing recomputed
    row = r"\| fft \| svm_rbf \| [\d.]+ \+- [\d.]+ cm \| [\d.]+ \| [\d.]+ / [\d.]+ \|"
    assert re.search(row, (out / "report.md").read_text())  # scores and latency, not 'failed'
    again = json.loads((out / "report.json").read_text())
    strip = lambda recs: [{k: v for k, v in r.items() if k != "eval_s"} for r in recs]  # noqa: E731
    assert strip(first) == strip(again)


@pytest.mark.slow  # a small report run between two plans
def test_report_plan_counts_fits_cached_and_to_do(tmp_path, make_tap_dataset, capsys):
    data = make_tap_dataset(tmp_path / "small.npz", n=24, seed=3)
    out = tmp_path / "rep"
    args = ["report", "--data", str(data), "--out", str(out), "--k", "2", "--features", "fft"]
    args += ["--models", "svm_rbf,svm_linear", "--no-gru", "--no-latency", "--no-taxels"]
    assert ext_sense([*args, "--plan"]) == 0
    text = capsys.readouterr().out
    # the table's 2 points and the default model at 8 rates (50 Hz .. 4 kHz; 4 kHz is the table's)
    assert "10 points, 20 fits (0 cached, 20 to do: fft+svm_rbf 18, fft+svm_linear 2); 2 " in text
    assert not (out / "report.md").exists()  # a plan writes nothing
    assert ext_sense(args) == 0
    capsys.readouterr()
    assert ext_sense([*args, "--plan"]) == 0
    assert "total: 10 points, 20 fits (20 cached in" in (text := capsys.readouterr().out)
    assert "nothing to do); 2 " in text


def test_the_rod_length_table_has_one_row_per_rod(tmp_path, make_tap_dataset):
    """Each data set's sections run three times (plan, deployed models, report): one row each."""
    rods = [
        make_tap_dataset(tmp_path / f"rod{r}.npz", n=24, seed=r, rod_length_m=r / 100)
        for r in (30, 50)
    ]
    out = tmp_path / "rep"
    args = ["report", "--out", str(out), "--k", "2", "--features", "fft", "--models", "svm_rbf"]
    args += [
        "--no-gru",
        "--no-latency",
        "--no-taxels",
        "--data",
        str(rods[0]),
        "--data",
        str(rods[1]),
    ]
    assert ext_sense(args) == 0
    text = (out / "report.md").read_text()
    table = text[text.index("## Rod length") :].splitlines()
    assert [line.split(" | ")[0] for line in table if line.startswith("| 0.")] == [
        "| 0.30",
        "| 0.50",
    ]


@pytest.mark.slow  # a local Dask cluster of 2 workers
def test_a_report_on_a_local_cluster_equals_one_in_process_deployed_models_included(
    tmp_path, make_tap_dataset
):
    """Every fit of a report, the deployed models of its latency column too, runs on the
    cluster's workers and lands in the cache: the same records and the same cache keys as in
    one process."""
    data = make_tap_dataset(tmp_path / "small.npz", n=24, seed=3)
    args = ["report", "--data", str(data), "--k", "2", "--features", "fft", "--models"]
    args += ["svm_rbf,svm_linear", "--no-gru", "--no-latency", "--no-taxels"]
    here, cluster = tmp_path / "here", tmp_path / "cluster"
    assert ext_sense([*args, "--out", str(here)]) == 0
    assert ext_sense([*args, "--out", str(cluster), "--workers", "2"]) == 0
    keys = [sorted(p.relative_to(d) for p in (d / "fits").rglob("*.pkl")) for d in (here, cluster)]
    assert keys[0] == keys[1]
    assert len(keys[0]) == 20 + 2  # the plan's 20 split fits and the 2 rows' deployed models
    strip = lambda recs: [{k: v for k, v in r.items() if k != "eval_s"} for r in recs]  # noqa: E731
    records = [json.loads((d / "report.json").read_text()) for d in (here, cluster)]
    assert strip(records[0]) == strip(records[1])
    text = (cluster / "report.md").read_text()
    assert (
        len(re.findall(r"\| fft \| svm_\w+ \| [\d.]+ \+- [\d.]+ cm \| [\d.]+ \| [\d.]+ / ", text))
        == 2
    )
