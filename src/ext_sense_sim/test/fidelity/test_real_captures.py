"""The fidelity check on the real NUSkin captures of ../shared/data (skipped when absent).

The regression test of issue 30 (build 4) holds each NUSkin tap scene against both real
rod-tap sessions of its rod, with the issue's tolerances on the medians of the pooled real
windows:

- events per window: simulated / real in x0.7-1.4;
- share of the window's events in its first 30 ms and in its last 100 ms: within +-0.07;
- share held by the 10 busiest taxels: within +-0.10;
- random-forest two-sample ROC AUC, simulated vs pooled real windows on those four
  statistics: at most the AUC between the two real sessions + 0.05;
- the 10 busiest taxels' events vary from tap to tap as little as in the real taps;
- one finger is the louder in at least 9 taps of 10, as in every real session.

The tolerances are the issue's: about the spread between the real sessions on each statistic
(docs/simulator.md, "Fidelity against the real sensor"); 200 simulated taps at the scene's
seed (``TAP_TRIALS``).
"""

from __future__ import annotations

import functools
from pathlib import Path

import numpy as np
import pytest

from ext_sense_sim.calibration.stages import window_medians
from ext_sense_sim.fidelity.captures import read_food_session, read_tap_session
from ext_sense_sim.fidelity.check import POOLED, SIMULATED, FidelityRun, pooled, run_fidelity
from ext_sense_sim.fidelity.compare import summarise
from ext_sense_sim.fidelity.table import format_table
from ext_sense_sim.fidelity.taps import TapWindows, tap_windows
from ext_sense_sim.scene import load_scene

ROD_DAYS = ("nuskin_rod_taps_2021-03-24", "nuskin_rod_taps_2021-03-25")
TAP_SCENES = (("tap_rod20_nuskin", 20), ("tap_rod30_nuskin", 30), ("tap_rod50_nuskin", 50))
"""The NUSkin tap scenes of the three real rods (``_day2`` and ``_wire`` are variants of the
30 cm one: a second simulated session, light taps for the ACES line)."""


@pytest.fixture(scope="module")
def rod_days(shared_data: Path) -> list[Path]:
    """The two real rod-tap sessions (24 and 25 March 2021)."""
    days = [shared_data / name for name in ROD_DAYS]
    absent = [str(d) for d in days if not d.is_dir()]
    if absent:
        pytest.skip(f"real rod-tap captures not available: {', '.join(absent)} absent")
    return days


# (rod cm, pooled real medians: events, first-30 ms, last-100 ms, busiest-10 shares)
REFERENCE_FIGURES = [
    (20, (5.8e3, 0.26, 0.12, 0.49)),
    (30, (9.3e3, 0.19, 0.23, 0.47)),
    (50, (10.5e3, 0.15, 0.35, 0.43)),
]


@pytest.mark.real_data
@pytest.mark.parametrize(("rod", "figures"), REFERENCE_FIGURES)
def test_the_window_rule_gives_the_reference_figures_on_the_real_taps(rod_days, rod, figures):
    # REFERENCE.md section 2 / issue 30's table, read by the same rule.
    windows = [tap_windows(read_tap_session(day, rod).captures) for day in rod_days]
    stats = {k: np.concatenate([w.stats[k] for w in windows]) for k in windows[0].stats}
    medians = summarise(stats)
    events, first, last, busiest = figures
    assert medians["events"]["median"] == pytest.approx(events, rel=0.1)
    assert medians["first_30ms"]["median"] == pytest.approx(first, abs=0.03)
    assert medians["last_100ms"]["median"] == pytest.approx(last, abs=0.03)
    assert medians["busiest_10"]["median"] == pytest.approx(busiest, abs=0.03)
    assert 30 <= medians["active_taxels"]["median"] <= 45


@pytest.mark.real_data
def test_missed_taps_are_the_captures_under_a_thousand_events(rod_days):
    missed = {
        (day.name, rod): tap_windows(read_tap_session(day, rod).captures).missed
        for day in rod_days
        for rod in (20, 30, 50)
    }
    assert sum(len(m) for m in missed.values()) == 6
    assert missed[("nuskin_rod_taps_2021-03-25", 30)] == ["temp_signal0"]


@pytest.mark.real_data
def test_the_food_sessions_are_read_with_their_motion_starts(food_sessions):
    sessions = [read_food_session(p) for p in food_sessions]
    assert [len(s.captures) for s in sessions] == [45, 53, 25]
    assert sessions[0].name == "nuskin_food_poking_2021-04-01"
    for s in sessions:
        marks = np.array([c.mark_bin for c in s.captures])
        assert np.all((marks > 40) & (marks < 80))  # 0.4-0.8 s after the capture's start


TAP_TRIALS = 200
"""Simulated taps per scene: with the former fixed tap force the windows were bimodal and 60
taps left a median that jumped from seed to seed; 200 hold it to about 0.02."""


@functools.cache
def _run(scene: str, days: tuple[Path, ...]) -> FidelityRun:
    return run_fidelity(load_scene(scene), list(days), trials=TAP_TRIALS)


def _fidelity(scene: str, days: tuple[Path, ...]) -> dict:
    return _run(scene, days).result


@pytest.mark.slow
@pytest.mark.real_data
@pytest.mark.timeout(900)
@pytest.mark.parametrize(("scene", "rod"), TAP_SCENES)
def test_each_tap_scene_is_within_the_real_sessions_spread(rod_days, scene, rod):
    result = _fidelity(scene, tuple(rod_days))
    assert result["rod_cm"] == rod
    assert result["groups"][POOLED]["windows"] >= 20
    assert result["groups"][SIMULATED]["windows"] >= 150
    failing = [t["stat"] for t in result["targets"] if not t["pass"]]
    assert not failing, f"{scene}: {', '.join(failing)} off target\n{format_table(result)}"


@pytest.mark.slow
@pytest.mark.real_data
@pytest.mark.timeout(900)
@pytest.mark.parametrize(("scene", "rod"), TAP_SCENES)
def test_each_tap_scene_varies_from_tap_to_tap_as_the_real_taps(rod_days, scene, rod):
    # The real windows' event counts hardly depend on where the rod was tapped (p75 / p25 about
    # 1.2); a fixed tap force gave 2-3 (contact_impulse.moment_exponent, docs/simulator.md).
    result = _fidelity(scene, tuple(rod_days))
    spread = {
        name: group["summary"]["events"]["p75"] / group["summary"]["events"]["p25"]
        for name, group in result["groups"].items()
    }
    assert spread[SIMULATED] < 1.25 * spread[POOLED], (scene, spread)


@pytest.mark.slow
@pytest.mark.real_data
@pytest.mark.timeout(900)
@pytest.mark.parametrize(("scene", "rod"), TAP_SCENES)
def test_the_busiest_taxels_fire_about_as_often_in_every_tap_as_the_real_ones(rod_days, scene, rod):
    # The same few taxels lead every real tap with nearly the same count (p75 / p25 of the 10
    # busiest taxels' events 1.08-1.19 by rod; grasp_transfer.gain_spread, docs/simulator.md).
    tables = _run(scene, tuple(rod_days)).tables
    real = pooled(tables, [day.name for day in rod_days])
    key = "busiest_10_events_p75_over_p25"
    sim, in_real = window_medians(tables[SIMULATED].stats)[key], window_medians(real)[key]
    assert abs(np.log(sim / in_real)) <= np.log(1.1), (scene, sim, in_real)


@pytest.mark.slow
@pytest.mark.real_data
@pytest.mark.timeout(900)
@pytest.mark.parametrize(("scene", "rod"), TAP_SCENES)
def test_a_forest_cannot_tell_each_tap_scene_from_the_real_taps(rod_days, scene, rod):
    result = _fidelity(scene, tuple(rod_days))
    assert result["auc"]["target"]["pass"], format_table(result)


def _same_louder_finger(windows: TapWindows) -> float:
    """Share of the tap windows whose louder finger is the one louder in most of them."""
    counts = windows.taxel_counts
    left_louder = counts[:, :40].sum(axis=1) > counts[:, 40:].sum(axis=1)
    return float(max(left_louder.mean(), 1.0 - left_louder.mean()))


@pytest.mark.slow
@pytest.mark.real_data
@pytest.mark.timeout(900)
@pytest.mark.parametrize(("scene", "rod"), TAP_SCENES)
def test_each_tap_scene_keeps_its_louder_finger_from_tap_to_tap_as_the_real_sessions(
    rod_days, scene, rod
):
    # In every real session one finger is the louder in 9 or 10 taps of 10 (the grasp's, not
    # the tap's); a louder finger drawn per tap gave 0.51-0.54 (docs/simulator.md).
    shares = {
        name: _same_louder_finger(w) for name, w in _run(scene, tuple(rod_days)).tables.items()
    }
    assert all(shares[day.name] >= 0.9 for day in rod_days), shares
    assert shares[SIMULATED] >= 0.9, (scene, shares)
