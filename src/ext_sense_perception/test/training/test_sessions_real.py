"""Sessions on the real food captures: cross-session protocol, score and calibrate round trip.

Reads ``../shared/data`` in place (skips with a message when it is absent).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from ext_sense.cli import main
from ext_sense_perception.data.sessions import load_session, pooled
from ext_sense_perception.online.model_card import read_card
from ext_sense_perception.profiles import CAPTURE_LEAD_NS


def test_sessions_carry_inferred_metadata_and_pool(food_sessions):
    s1, s3, s5 = (load_session(p) for p in food_sessions)
    assert (s1.info.date, s3.info.date, s5.info.date) == ("2021-04-01", "2021-04-03", "2021-04-05")
    assert s3.info.baseline == "zero.tact"
    assert s1.info.baseline == ""
    assert s3.info.labels == ("cucumber", "dragonfruit", "honeydew", "tofu", "watermelon")
    # 1 April has its arm bags, the others not: each gets its default anchor
    assert (s1.windows.anchor, s3.windows.anchor) == ("arm_motion", "capture_start")
    with pytest.raises(Exception, match="anchor"):
        pooled([s1, s3])  # windows cut at other anchors do not pool
    s1c = load_session(food_sessions[0], anchor="capture_start")
    both = pooled([s1c, s3])
    assert len(both.y) == 44 + 52
    assert set(both.session_of.tolist()) == {s1.info.name, s3.info.name}
    assert len(set(both.groups.tolist())) == 96  # trial groups kept apart per session


def test_capture_start_windows_begin_at_the_capture_marker(food_sessions):
    ws = load_session(food_sessions[1], anchor="capture_start").windows
    assert ws.geometry.pre_ns == CAPTURE_LEAD_NS
    first = food_sessions[1] / "cucumber_zero_1111.tact"
    t0 = float(first.read_text().split("\n", 1)[0].split()[3])
    events = np.loadtxt(first, ndmin=2)[1:-1]
    bins = np.round((events[:, 3] - t0) * 100).astype(int)  # stamps are in hundredths
    per_bin = np.bincount(bins, minlength=350)[:350]
    assert np.array_equal(ws.X[0].sum(axis=0), per_bin)


def test_contact_anchor_names_the_trials_without_a_detected_contact(food_sessions):
    ws = load_session(food_sessions[0], anchor="contact").windows
    assert ws.anchor == "contact"
    assert ws.geometry.pre_ns > 0
    missed = [e for e in ws.excluded if "no contact detected" in e]
    assert len(ws.y) + len(missed) == 44
    assert "watermelon" in ws.class_names
    assert missed


@pytest.mark.slow  # four recipe fits
def test_cross_session_protocol_on_the_three_days(food_sessions, tmp_path, capsys):
    out = tmp_path / "cs.json"
    args = ["evaluate", "--protocol", "cross-session", "--anchor", "capture_start"]
    for p in food_sessions:
        args += ["--data", str(p)]
    assert main([*args, "--json", str(out)]) == 0
    rec = json.loads(out.read_text())
    rows = {r["session"]: r for r in rec["sessions"]}
    assert rows["nuskin_food_poking_2021-04-05"]["skipped"].startswith("no class in common")
    assert rows["nuskin_food_poking"]["classes_in_common"] == ["tofu", "watermelon"]
    assert rows["nuskin_food_poking"]["n_windows"] == 22
    assert rows["nuskin_food_poking_2021-04-03"]["n_windows"] == 30
    # decisions among the session's own foods hold across days; unrestricted they do not
    assert rec["n_scored"] == 2
    assert rec["mean"] >= 0.80
    assert rec["mean_unrestricted"] < rec["mean"]
    assert "mean over 2 sessions" in capsys.readouterr().out


def _calibration_folder(session: Path, out: Path, per_class: int) -> Path:
    """A folder of the first ``per_class`` trials of each class of ``session`` (symlinks)."""
    out.mkdir()
    for label in ("cucumber", "dragonfruit", "honeydew", "tofu", "watermelon"):
        tacts = [t for t in sorted(session.glob(f"{label}_zero_*.tact")) if "_raw" not in t.name]
        for tact in tacts[:per_class]:
            (out / tact.name).symlink_to(tact)
    return out


@pytest.mark.slow  # two recipe fits and two scorings of 52 windows
def test_score_and_calibrate_round_trip(food_sessions, tmp_path, capsys):
    d1, d3, d5 = (str(p) for p in food_sessions)
    bundle, calibrated = tmp_path / "b", tmp_path / "b_cal"
    train = ["train", "--data", d1, "--data", d5, "--anchor", "capture_start"]
    assert main([*train, "--out", str(bundle)]) == 0
    card = read_card(bundle)
    assert card.anchor == "capture_start"
    assert card.sessions == ("nuskin_food_poking", "nuskin_food_poking_2021-04-05")

    before = tmp_path / "before.json"
    assert main(["score", str(bundle), "--data", d3, "--json", str(before)]) == 0
    rec = json.loads(before.read_text())
    assert rec["task"] == "food_identification"
    assert rec["metric"] == "accuracy"
    assert rec["n_windows"] == 30
    assert rec["label_set"] == ["tofu", "watermelon"]
    assert {u["label"] for u in rec["unknown"]} == {"cucumber", "dragonfruit", "honeydew"}
    assert len(rec["unknown"]) == 22
    assert 0 <= rec["calibration"]["expected_calibration_error"] <= 1
    assert sum(map(sum, rec["confusion"])) == 30
    assert rec["value"] >= 0.8

    calib = _calibration_folder(food_sessions[1], tmp_path / "calib", per_class=2)
    assert main(["calibrate", str(bundle), "--data", str(calib), "--out", str(calibrated)]) == 0
    new = read_card(calibrated)
    assert new.calibration["trials_per_class"]["tofu"] == 2
    assert new.calibration["base_model"] == card.id
    assert new.id != card.id
    assert set(new.label_set) == {"cucumber", "dragonfruit", "honeydew", "tofu", "watermelon"}
    assert {"cucumber", "dragonfruit"} <= set(new.class_names)  # the day's new foods learnt

    after = tmp_path / "after.json"
    assert main(["score", str(calibrated), "--data", d3, "--json", str(after)]) == 0
    rec2 = json.loads(after.read_text())
    assert rec2["n_windows"] == 52
    assert rec2["unknown"] == []
    assert "calibrated to session 'calib'" in capsys.readouterr().out
