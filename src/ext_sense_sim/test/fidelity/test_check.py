import json
import re

import numpy as np
import pytest

from ext_sense.cli import main as ext_sense_main
from ext_sense_sim.fidelity.captures import LATENCY_NS, simulate
from ext_sense_sim.fidelity.taps import tap_windows
from ext_sense_sim.scene import load_scene


def test_simulated_trials_are_reduced_to_ten_millisecond_host_bins():
    scene = load_scene("tap_rod20_nuskin")
    run = simulate(scene, 3, seed=4, extra_s=0.1)
    again = simulate(scene, 3, seed=4, extra_s=0.1)
    assert len(run.captures) == 3
    bins = round((scene.trial_s + 0.1) * 100)  # the trial's end, the last bin partly
    late = -(-LATENCY_NS // 10_000_000)  # bins the host's last transfer may close after it
    for cap, twin in zip(run.captures, again.captures, strict=True):
        np.testing.assert_array_equal(cap.bins, twin.bins)
        assert bins <= cap.span_bins <= bins + 1 + late
        assert np.all(np.diff(cap.bins) >= 0)
        assert 0 <= cap.bins.min() <= cap.bins.max() < cap.span_bins
        assert 0 <= cap.mark_bin < cap.span_bins
    found = tap_windows(run.captures)
    # the rule finds a simulated tap within a bin of its true onset
    assert np.all(np.abs(found.onset_error_ms) <= 20)


def test_the_cli_compares_a_scene_with_two_real_sessions(tmp_path, noisy_day, capsys):
    a = noisy_day(tmp_path / "taps_2021-03-24", 20, 4, seed=1)
    b = noisy_day(tmp_path / "taps_2021-03-25", 20, 4, seed=2)
    out = tmp_path / "out"
    args = ["sim", "fidelity", "tap_rod20_nuskin", "--real", str(a), "--real", str(b)]
    args += ["--trials", "3", "--seed", "3", "--check"]
    code = ext_sense_main([*args, "--json", str(out / "r.json"), "--figure", str(out / "r.png")])
    result = json.loads((out / "r.json").read_text())
    assert code == (0 if result["pass"] else 1)
    assert result["sessions"] == ["taps_2021-03-24", "taps_2021-03-25"]
    assert result["rod_cm"] == 20
    assert result["trials"] == 3
    for name in result["sessions"]:
        assert result["groups"][name]["windows"] == 4
    assert [t["stat"] for t in result["targets"]] == [
        "events",
        "first_30ms",
        "last_100ms",
        "busiest_10",
    ]
    auc = result["auc"]["target"]
    assert 0.0 <= auc["yardstick"] <= 1.0
    assert auc["limit"] == pytest.approx(auc["yardstick"] + 0.05)
    assert set(auc["sim_vs_session"]) == set(result["sessions"])
    assert (out / "r.png").read_bytes()[:4] == b"\x89PNG"
    printed = capsys.readouterr().out
    assert "real pooled" in printed
    assert "2021-03-24" in printed
    assert "targets per real session" in printed
    assert "fidelity targets: " in printed


@pytest.mark.parametrize(
    ("scene", "real", "message"),
    [
        ("tap_rod30_nuskin", "nowhere", "The --real folder .*nowhere' does not exist"),
        ("tap_rod30_nuskin", "empty", "holds no rod-tap captures"),
        ("food_fork_nuskin", "empty", "holds no food-poking captures"),
        ("tap_rod30_biotac", "empty", "simulates the biotac; the real captures are NUSkin's"),
        ("handover_rod_nuskin", "empty", "has no real captures"),
        ("no_such_scene", "empty", "neither a shipped scene"),
    ],
)
def test_bad_input_is_one_line_and_exit_2(tmp_path, capsys, scene, real, message):
    (tmp_path / "empty").mkdir()
    code = ext_sense_main(["sim", "fidelity", scene, "--real", str(tmp_path / real)])
    err = capsys.readouterr().err
    assert code == 2
    assert len(err.strip().splitlines()) == 1
    assert err.startswith("ext-sense sim fidelity: ")
    assert re.search(message, err)


def test_a_trial_count_below_one_is_refused(tmp_path, capsys):
    code = ext_sense_main(["sim", "fidelity", "tap_rod30_nuskin", "--real", str(tmp_path)])
    assert code == 2
    code = ext_sense_main(
        ["sim", "fidelity", "tap_rod30_nuskin", "--real", str(tmp_path), "--trials", "0"]
    )
    assert code == 2
    assert "--trials must be >= 1. Got 0" in capsys.readouterr().err
