"""The tap stage's joint-distribution target: the two-sample AUC of the simulated windows against
the real ones, aimed at 0.5 (no forest tells them apart). Simulated captures stand in for the
real ones: a scene against its own windows scores near 0.5, against another rod's near 1."""

from __future__ import annotations

import pytest

from ext_sense_sim.calibration.stages import TAP_TOLERANCES, tap_measure, tap_medians
from ext_sense_sim.fidelity.captures import simulate
from ext_sense_sim.fidelity.taps import WINDOW_S
from ext_sense_sim.scene import load_scene

TRIALS = 40


@pytest.fixture(scope="module")
def rod30_windows():
    scene = load_scene("tap_rod30_nuskin")
    return scene, simulate(scene, TRIALS, 7, extra_s=WINDOW_S).captures


def test_the_tap_stage_aims_the_auc_at_indistinguishable(rod30_windows) -> None:
    _, captures = rod30_windows
    assert tap_medians(captures)["auc_vs_real"] == 0.5
    assert "auc_vs_real" in TAP_TOLERANCES


def test_a_scene_against_its_own_windows_is_near_chance_and_another_rod_is_told_apart(
    rod30_windows,
) -> None:
    scene, captures = rod30_windows
    same = tap_measure(TRIALS, 7, captures)(scene)  # the very same windows
    other = tap_measure(TRIALS, 7, captures)(load_scene("tap_rod20_nuskin"))
    assert same["auc_vs_real"] < 0.6
    assert other["auc_vs_real"] > 0.9
    assert same["events"] == pytest.approx(tap_medians(captures)["events"])
