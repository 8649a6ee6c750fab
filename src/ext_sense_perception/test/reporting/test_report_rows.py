"""report.json rows: each says its study and parameter; --sim-commit and --update."""

from __future__ import annotations

import json
import re
from collections import Counter
from pathlib import Path

import numpy as np
import pytest

from ext_sense.cli import main as ext_sense
from ext_sense_perception.errors import PerceptionError
from ext_sense_perception.reporting.document import read_report
from ext_sense_perception.reporting.report import build_report
from ext_sense_perception.reporting.runner import Study
from ext_sense_perception.reporting.scores import fmt_values


def simulated(path: Path, scene: str, seed: int) -> Path:
    """The synthetic data set with the scene and seed keys a simulator dataset.npz has."""
    with np.load(path, allow_pickle=False) as z:
        arrays = {k: z[k] for k in z.files}
    np.savez(path, scene=np.array(scene), seed=np.array(seed, dtype=np.int64), **arrays)
    return path


@pytest.fixture(scope="module")
def quick_report(tmp_path_factory, make_tap_dataset) -> tuple[list[dict], str]:
    """A quick report (every section) of a small simulated 30 cm rod at commit abc1234."""
    root = tmp_path_factory.mktemp("rows")
    (root / "tap_rod30_nuskin").mkdir()
    data = make_tap_dataset(root / "tap_rod30_nuskin" / "dataset.npz", n=20, seed=3)
    simulated(data, "tap_rod30_nuskin", 1)
    md = build_report(
        [data], root / "rep", k=2, quick=True, gru=False, models=["svm_rbf"], sim_commit="abc1234"
    )
    return json.loads((root / "rep" / "report.json").read_text()), md.read_text()


@pytest.mark.slow  # a quick report run (every section)
def test_every_row_says_its_study_parameters_and_source(quick_report):
    rows, _ = quick_report
    studies = Counter(r["study"] for r in rows)
    assert set(studies) == {s.value for s in Study}
    for r in rows:
        assert r["dataset"] == "tap_localization_nuskin_tap_rod30_nuskin"
        assert (r["task"], r["sensor"], r["rod_m"]) == ("tap_localization", "nuskin", 0.3)
        assert (r["source"], r["scene"], r["seed"]) == ("simulator", "tap_rod30_nuskin", 1)
        assert r["sim_commit"] == "abc1234"
    by = {s: [r for r in rows if r["study"] == s.value] for s in Study}
    assert [(r["features"], r["model"]) for r in by[Study.MODELS]] == [
        ("fft", "svm_rbf"),
        ("baseline", "svm_rbf"),
    ]
    # the default model, then the paper's linear one beside it, at every window
    assert [(r["model"], r["post_ms"]) for r in by[Study.DECISION_LATENCY]] == [
        (m, p) for p in (25, 50, 100, 150, 250) for m in ("svm_rbf", "svm_linear")
    ]
    assert all(r["rate_hz"] is None for s in Study if s is not Study.SAMPLING_RATE for r in by[s])
    assert [r["rate_hz"] for r in by[Study.SAMPLING_RATE]] == [50, 250, 1000, 4000]
    main = by[Study.MODELS][0]
    # a resampled point is its own evaluation, not the main one under another name
    assert main["point"] not in {r["point"] for r in by[Study.SAMPLING_RATE]}
    assert len({r["point"] for r in by[Study.SAMPLING_RATE]}) == 4
    assert [r["rod_m"] for r in by[Study.ROD_LENGTH]] == [0.3]
    assert by[Study.ROD_LENGTH][0]["point"] == main["point"]


@pytest.mark.slow  # a quick report run (every section)
def test_taxel_rows_name_their_channels_and_match_the_markdown(quick_report):
    rows, text = quick_report
    taxels = [r for r in rows if r["study"] == "taxels"]
    for model in ("svm_rbf", "svm_linear"):
        channels = [r["channels"] for r in taxels if r["model"] == model]
        assert channels[:3] == ["all", "left", "right"]
        assert re.fullmatch(r"taxel:\d+", channels[3])
    single = [r for r in taxels if r["channels"].startswith("taxel:")]
    assert [r["model"] for r in single] == ["svm_rbf", "svm_linear"]
    chosen_md = re.search(r"Taxel chosen in each split: (.*)\.", text)[1]
    for r in single:
        n = int(r["channels"].split(":")[1])
        assert n == Counter(r["taxel_per_split"]).most_common(1)[0][0]
        assert set(r["taxel_per_split"]) <= set(r["taxel_candidates"])
        assert 1 <= n <= 80
        assert f"{r['model']}: {', '.join(map(str, r['taxel_per_split']))}" in chosen_md
    # the markdown's rate table shows the rows' scores
    for r in rows:
        if r["study"] == "sampling_rate":
            line = f"| {int(r['rate_hz'])} | {fmt_values(r['metric'], r['mean'], r['std'])} |"
            assert line in text
    assert "Simulated: scene `tap_rod30_nuskin`, seed 1, simulator commit abc1234." in text
    assert "| tap_localization_nuskin_tap_rod30_nuskin | simulator | tap_rod30_nuskin, 1 " in text


def _report(out: Path, data: Path, commit: str, *extra: str) -> int:
    args = ["report", "--data", str(data), "--out", str(out), "--k", "2", "--features", "fft"]
    args += ["--models", "svm_rbf", "--no-gru", "--no-latency", "--no-taxels", "--quick"]
    return ext_sense([*args, "--sim-commit", commit, *extra])


@pytest.mark.slow  # four small report runs
def test_update_replaces_only_the_data_sets_it_evaluates(tmp_path, make_tap_dataset):
    rods = {}
    for r in (30, 50):
        (tmp_path / f"tap_rod{r}_nuskin").mkdir()
        rods[r] = simulated(
            make_tap_dataset(
                tmp_path / f"tap_rod{r}_nuskin" / "dataset.npz", n=24, seed=r, rod_length_m=r / 100
            ),
            f"tap_rod{r}_nuskin",
            1,
        )
    out = tmp_path / "rep"
    assert _report(out, rods[30], "aaaa111") == 0
    first = json.loads((out / "report.json").read_text())
    assert _report(out, rods[50], "bbbb222", "--update") == 0
    assert _report(out, rods[30], "cccc333", "--update") == 0
    rows = json.loads((out / "report.json").read_text())
    commits = {(r["rod_m"], r["sim_commit"]) for r in rows}
    assert commits == {(0.3, "cccc333"), (0.5, "bbbb222")}
    rod30 = [r for r in rows if r["rod_m"] == 0.3]
    strip = lambda recs: [  # noqa: E731
        {k: v for k, v in r.items() if k not in ("eval_s", "sim_commit")} for r in recs
    ]
    assert strip(rod30) == strip(first)  # the same rows, from the cache, now at cccc333
    text = (out / "report.md").read_text()
    order = list(dict.fromkeys(r["rod_m"] for r in rows))
    assert order == [0.3, 0.5]  # the rows in the sections' order
    assert text.index("| tap_localization_nuskin_tap_rod30_nuskin | simulator") < text.index(
        "| tap_localization_nuskin_tap_rod50_nuskin | simulator"
    )
    headings = [line for line in text.splitlines() if line.startswith("## ")]
    assert headings[0] == "## Data sets"
    assert "tap_rod30_nuskin/dataset.npz" in headings[1]  # replaced in place, before the 50 cm
    assert "tap_rod50_nuskin/dataset.npz" in headings[2]
    assert headings[3].startswith("## Rod length")
    assert text.count("### Sampling rate") == 2
    rod_table = text[text.index("## Rod length") :]
    mae = r"[\d.]+ \+- [\d.]+ cm \| [\d.]+"
    assert re.search(rf"\| 0\.30 \| nuskin \| {mae} \| cccc333 \|", rod_table)
    assert re.search(rf"\| 0\.50 \| nuskin \| {mae} \| bbbb222 \|", rod_table)
    # without --update the report is this run's alone
    assert _report(out, rods[50], "bbbb222") == 0
    rows = json.loads((out / "report.json").read_text())
    assert {r["rod_m"] for r in rows} == {0.5}
    assert "tap_rod30_nuskin" not in (out / "report.md").read_text()


def test_read_report_splits_data_set_sections_and_drops_the_rebuilt_ones(tmp_path):
    (tmp_path / "report.json").write_text("[]")
    (tmp_path / "report.md").write_text(
        "# ext_sense perception report\n\nintro\n\n## Data sets\n\n| a |\n\n"
        "## tap_localization, nuskin (1000 windows; `/gone/tap_rod30_nuskin/dataset.npz`)\n\n"
        "### Features and models\n\n| x |\n\n"
        "## food_identification, nuskin (44 windows; `../shared/data/nuskin_food_poking`)\n\n"
        "| y |\n\n## Rod length (tap localisation, default model)\n\n| 0.30 |\n"
        "(In progress: 1 of 2 data sets.)\n"
    )
    sections, records = read_report(tmp_path)
    assert records == []
    assert list(sections) == [
        "tap_localization_nuskin_tap_rod30_nuskin",
        "food_identification_nuskin_nuskin_food_poking",
    ]
    assert sections["tap_localization_nuskin_tap_rod30_nuskin"][2:5] == [
        "### Features and models",
        "",
        "| x |",
    ]
    assert sections["food_identification_nuskin_nuskin_food_poking"][-2:] == ["| y |", ""]
    assert read_report(tmp_path / "none") == ({}, [])


@pytest.mark.parametrize(
    ("text", "match"),
    [("{not json", "Cannot read the former report"), ('{"a": 1}', "must be a list of rows")],
)
def test_read_report_refuses_a_bad_report_json(tmp_path, text, match):
    (tmp_path / "report.json").write_text(text)
    (tmp_path / "report.md").write_text("# r\n")
    with pytest.raises(PerceptionError, match=match):
        read_report(tmp_path)


@pytest.mark.parametrize("commit", ["", "abc", "abc 123", "a|b`c1234"])
def test_cli_report_refuses_a_bad_sim_commit_before_any_work(
    tmp_path, capsys, make_tap_dataset, commit
):
    data = make_tap_dataset(tmp_path / "small.npz", n=20, seed=3)
    out = tmp_path / "rep"
    rc = ext_sense(["report", "--data", str(data), "--out", str(out), "--sim-commit", commit])
    assert rc == 2
    assert "'sim_commit' parameter must be a commit name" in capsys.readouterr().err
    assert not out.exists()


@pytest.mark.parametrize(
    ("path", "name"),
    [
        ("/d/tap_rod30_nuskin/dataset.npz", "tap_localization_nuskin_tap_rod30_nuskin"),
        ("/d/data/rod30.npz", "tap_localization_nuskin_data_rod30"),
        ("../shared/data/nuskin_food_poking", "tap_localization_nuskin_nuskin_food_poking"),
    ],
)
def test_dataset_names_come_from_the_path_alone(path, name):
    from ext_sense_perception.reporting.sections import dataset_name_of

    assert dataset_name_of("tap_localization", "nuskin", path) == name


def test_two_data_sets_of_one_name_are_refused(tmp_path, capsys, make_tap_dataset):
    data = make_tap_dataset(tmp_path / "small.npz", n=20, seed=3)
    args = ["report", "--out", str(tmp_path / "rep"), "--plan", "--quick"]
    assert ext_sense([*args, "--data", str(data), "--data", str(data)]) == 2
    assert "share the report name 'tap_localization_nuskin_" in capsys.readouterr().err
