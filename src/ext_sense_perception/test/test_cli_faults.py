"""Hostile inputs to ``ext-sense train|evaluate|score`` (issue #32): each refused in one line.

Every probe ends with one line ``ext-sense: error: ...`` on stderr naming what is wrong, exit
status 2 and no traceback: ``session.json`` fields of the wrong kind or naming another sensor
(one schema for every loader), training on one class, ``--anytime-ms`` outside the training
windows, a bundle scored on data of another task, and ``--data`` given a folder that holds no
captures. The probes on the real captures read ``../shared/data`` in place (they skip, saying
so, when it is absent).
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from ext_sense.cli import main
from ext_sense_perception.data.sessions import load_session, metadata_file
from ext_sense_perception.errors import PerceptionError
from ext_sense_perception.online.model_card import read_card


def _refused(capsys: pytest.CaptureFixture[str], args: list[str]) -> str:
    """Run ``ext-sense ARGS``: exit 2 and exactly one error line on stderr; returns the line."""
    code = main(args)
    err = capsys.readouterr().err
    assert code == 2, err
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith("ext-sense: error: "), err
    return lines[0]


def _session_of(captures: Path, out: Path, labels: tuple[str, ...] | None = None) -> Path:
    """A session folder of links to the captures of ``captures`` (of ``labels`` only)."""
    out.mkdir()
    for tact in sorted(captures.glob("*_zero_*.tact")):
        label = tact.name.split("_zero_")[0]
        if "_raw" not in tact.name and (labels is None or label in labels):
            (out / tact.name).symlink_to(tact)
    return out


@pytest.fixture(scope="module")
def food_day3(food_sessions: list[Path], tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The 3 April 2021 captures in a folder of their own (a session.json can go beside them)."""
    return _session_of(food_sessions[1], tmp_path_factory.mktemp("day3") / "day3")


@pytest.fixture(scope="module")
def tap_bundle(tap_npz: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A tap-localization bundle of the synthetic taps, stored as ``tap_localization_nuskin``."""
    out = tmp_path_factory.mktemp("models") / "tap_localization_nuskin"
    assert main(["train", "--data", str(tap_npz), "--anytime-ms", "none", "--out", str(out)]) == 0
    return out


@pytest.fixture(scope="module")
def capture_bundle(food_sessions: list[Path], tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A food bundle of the 1 April captures cut at the capture's start (its card's anchor)."""
    out = tmp_path_factory.mktemp("food") / "food"
    args = ["train", "--data", str(food_sessions[0]), "--anchor", "capture_start"]
    assert main([*args, "--out", str(out)]) == 0
    assert read_card(out).anchor == "capture_start"
    return out


BAD_SESSION_FILES = [
    ({"labels": "tofu"}, "'labels' must be a list of distinct non-empty strings", 'string "tofu"'),
    ({"labels": 5}, "'labels' must be a list", "number 5"),
    ({"labels": ["tofu", 3]}, "'labels' must be a list", 'list ["tofu", 3]'),
    ({"labels": ["tofu", "tofu"]}, "'labels' must be a list of distinct", 'list ["tofu", "tofu"]'),
    ({"sensor": "bio tac"}, "'sensor' must be one of 'nuskin', 'biotac'", 'string "bio tac"'),
    ({"date": "3/4/2021"}, "'date' must be a day as a 'YYYY-MM-DD'", 'string "3/4/2021"'),
    ({"name": None}, "'name' must be a non-empty string", "null"),
    ({"notes": ["a"]}, "'notes' must be a string", 'list ["a"]'),
    ({"colour": "red"}, "must be an object with fields among", "the unknown fields ['colour']"),
    (["tofu"], "must be an object with fields among", 'list ["tofu"]'),
]


@pytest.mark.parametrize(("body", "expected", "got"), BAD_SESSION_FILES)
def test_a_session_file_breaking_the_schema_is_refused_by_every_loader(
    body, expected, got, food_npz, tmp_path, capsys
):
    data = tmp_path / "day.npz"
    data.write_bytes(Path(food_npz).read_bytes())
    meta = metadata_file(data)
    meta.write_text(json.dumps(body))
    line = _refused(capsys, ["train", "--data", str(data), "--out", str(tmp_path / "b")])
    assert f"Session metadata {str(meta)!r}" in line
    assert expected in line
    assert f"Got {got} instead." in line
    assert not (tmp_path / "b").exists()
    with pytest.raises(PerceptionError) as err:  # the library's loader: the same schema
        load_session(data)
    assert f"ext-sense: error: {err.value}" == line


def test_a_session_file_naming_another_sensor_is_refused_by_the_commands(
    food_npz, tmp_path, capsys
):
    data = tmp_path / "day.npz"
    data.write_bytes(Path(food_npz).read_bytes())
    metadata_file(data).write_text('{"sensor": "biotac"}')
    for command in (["train", "--out", str(tmp_path / "b")], ["evaluate", "--k", "2"]):
        line = _refused(capsys, [*command, "--data", str(data)])
        assert line.endswith(
            "the field 'sensor' must be the data's 'nuskin'. Got 'biotac' instead."
        )
    line = _refused(capsys, ["evaluate", "--protocol", "cross-session", "--data", str(data)])
    assert "'sensor' must be the data's 'nuskin'" in line  # cross-session loads them too


@pytest.mark.real_data
@pytest.mark.parametrize(
    ("body", "expected"),
    [
        ({"labels": "tofu"}, "the field 'labels' must be a list"),  # was split into t, o, f, u
        ({"labels": 5}, "the field 'labels' must be a list"),  # was a TypeError traceback
        ({"sensor": "biotac"}, "the field 'sensor' must be the data's 'nuskin'"),  # was rc 0
    ],
)
def test_session_files_beside_the_real_captures_are_checked_when_scoring(
    body, expected, food_day3, capture_bundle, capsys
):
    meta = food_day3 / "session.json"
    meta.write_text(json.dumps(body))
    try:
        line = _refused(capsys, ["score", str(capture_bundle), "--data", str(food_day3)])
    finally:
        meta.unlink()
    assert f"Session metadata {str(meta)!r}: {expected}" in line


def test_a_bad_session_file_ends_the_process_with_2_and_no_traceback(food_npz, tmp_path):
    data = tmp_path / "day.npz"
    data.write_bytes(Path(food_npz).read_bytes())
    metadata_file(data).write_text('{"labels": 5}')
    args = ["train", "--data", str(data), "--out", str(tmp_path / "b")]
    run = subprocess.run(
        [sys.executable, "-m", "ext_sense.cli", *args], capture_output=True, text=True, timeout=60
    )
    assert run.returncode == 2, run.stderr
    assert "Traceback" not in run.stderr
    assert run.stderr.strip().splitlines() == [
        f"ext-sense: error: Session metadata '{data}.session.json': the field 'labels' must be a "
        'list of distinct non-empty strings, e.g. ["tofu", "apple"]. Got number 5 instead.'
    ]


def test_training_on_one_class_is_refused(food_npz, tmp_path, capsys):
    with np.load(food_npz) as z:
        arrays = dict(z)
    arrays["y"] = np.full(len(arrays["y"]), "tofu")
    one = tmp_path / "tofu.npz"
    np.savez(one, **arrays)
    line = _refused(capsys, ["train", "--data", str(one), "--out", str(tmp_path / "b")])
    assert line == (
        "ext-sense: error: Classification needs windows of at least 2 classes to train a model. "
        f"Got only ['tofu'] in {str(one)!r}."
    )
    assert not (tmp_path / "b").exists()


@pytest.mark.real_data
def test_training_on_the_captures_of_one_food_is_refused(food_sessions, tmp_path, capsys):
    tofu = _session_of(food_sessions[1], tmp_path / "tofu", ("tofu",))
    line = _refused(capsys, ["train", "--data", str(tofu), "--out", str(tmp_path / "b")])
    assert "at least 2 classes" in line
    assert "Got only ['tofu']" in line
    line = _refused(capsys, ["evaluate", "--data", str(tofu)])  # evaluate said it already
    assert "at least 2 classes" in line


@pytest.mark.parametrize("value", ["inf", "nan", "0", "-50", "1e12", "0.5", "25,-inf", "250"])
def test_anytime_times_outside_the_training_windows_are_refused(value, tap_npz, tmp_path, capsys):
    out = tmp_path / "b"
    line = _refused(
        capsys, ["train", "--data", str(tap_npz), f"--anytime-ms={value}", "--out", str(out)]
    )
    # the synthetic taps' windows: 50 ms before to 250 ms after the onset, 1 ms samples
    assert line == (
        "ext-sense: error: The '--anytime-ms' option must list times within the training "
        "windows' post-onset span, each in [1, 250) ms (at least one 1 ms sample after the "
        f"onset, shorter than the 250 ms windows). Got {value!r} instead."
    )
    assert not out.exists()


def test_anytime_range_follows_the_window_geometry(food_npz, tmp_path, capsys):
    # the synthetic food windows begin 2 s after the onset and end 8 s after it (10 ms samples)
    args = ["train", "--data", str(food_npz), "--anytime-ms", "1000", "--out", str(tmp_path / "b")]
    assert "each in [2010, 8000) ms" in _refused(capsys, args)
    args = ["train", "--data", str(food_npz), "--post-ms", "inf", "--out", str(tmp_path / "b")]
    assert "'--post-ms' option must be a finite number" in _refused(capsys, args)


def test_anytime_times_at_the_ends_of_the_range_are_kept(tap_npz, tmp_path, capsys):
    out = tmp_path / "b"
    assert (
        main(["train", "--data", str(tap_npz), "--anytime-ms", "1,249.5", "--out", str(out)]) == 0
    )
    assert read_card(out).anytime_post_ms == (1.0, 249.0)  # cut on the windows' 1 ms samples
    assert "anytime models for [1.0, 249.0] ms" in capsys.readouterr().out


@pytest.mark.real_data
def test_a_tap_model_scored_on_food_captures_is_refused(tap_bundle, food_day3, monkeypatch, capsys):
    monkeypatch.setenv("EXT_SENSE_MODELS", str(tap_bundle.parent))
    line = _refused(capsys, ["score", "tap_localization_nuskin", "--data", str(food_day3)])
    assert line == (
        f"ext-sense: error: The data {str(food_day3)!r} holds food_identification/nuskin "
        f"windows, but the bundle {str(tap_bundle)!r} is a tap_localization/nuskin model: give "
        "it tap_localization/nuskin sessions, or a food_identification/nuskin bundle."
    )


def test_a_bundle_scored_on_a_dataset_of_another_task_is_refused(tap_bundle, food_npz, capsys):
    line = _refused(capsys, ["score", str(tap_bundle), "--data", str(food_npz)])
    assert "holds food_identification/nuskin windows, but the bundle" in line
    line = _refused(capsys, ["score", str(tap_bundle), "--task", "food", "--data", str(food_npz)])
    assert "the '--task' option asks for food_identification" not in line
    assert "is a tap_localization/nuskin model" in line


def test_training_data_of_another_task_than_asked_is_refused(food_npz, tmp_path, capsys):
    args = ["train", "--task", "tap_localization", "--data", str(food_npz), "--out", str(tmp_path)]
    line = _refused(capsys, args)
    assert line.endswith(
        "holds food_identification/nuskin windows, but the '--task' option asks for "
        "tap_localization."
    )


@pytest.mark.real_data
def test_a_capture_bundle_scored_on_a_tap_dataset_names_the_task_not_an_anchor(
    capture_bundle, tap_npz, capsys
):
    line = _refused(capsys, ["score", str(capture_bundle), "--data", str(tap_npz)])
    assert "anchor" not in line  # the bundle's anchor applies to capture folders only
    assert f"{str(tap_npz)!r} holds tap_localization/nuskin windows" in line
    assert "is a food_identification/nuskin model" in line


def test_a_sim_run_folder_as_data_says_what_it_is_and_what_to_give(tmp_path, capsys):
    run = tmp_path / "run"
    assert (
        main(
            [
                "sim",
                "run",
                "tap_rod30_nuskin",
                "--trials",
                "2",
                "--formats",
                "npz",
                "--out",
                str(run),
            ]
        )
        == 0
    )
    capsys.readouterr()
    line = _refused(capsys, ["train", "--data", str(run), "--out", str(tmp_path / "b")])
    assert line == (
        f"ext-sense: error: {str(run)!r} is the output folder of 'ext-sense sim run', not a "
        f"food-poking capture folder; give one of its sessions instead: --data {run}/dataset.npz."
    )
    empty = tmp_path / "empty"
    empty.mkdir()
    line = _refused(capsys, ["evaluate", "--data", str(empty)])
    assert f"{str(empty)!r} is not a food-poking capture folder" in line
