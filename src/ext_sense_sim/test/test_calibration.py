"""The calibration's search, targets and scene edits (no simulation: a known loss surface)."""

from __future__ import annotations

import math

import numpy as np
import pytest
import yaml

from ext_sense_sim.calibration import calibrate_scene
from ext_sense_sim.calibration.search import (
    FreeParameter,
    FreeWidth,
    Target,
    effect_lines,
    fit,
    start_values,
    with_values,
)
from ext_sense_sim.calibration.stages import TAP_TOLERANCES, Stage, window_medians
from ext_sense_sim.errors import SceneError
from ext_sense_sim.scene import load_scene, scene_from_dict

FORCE = FreeParameter("contact_impulse", "force_n", 0.01, 10.0, spread=(0.5, 2.5))
DAMPING = FreeParameter("beam_modes", "grasp_damping_ratio", 0.001, 0.2)


def _params(scene, effect):
    return dict(scene.effects)[effect]


WIDTH = FreeWidth("contact_impulse", "force_n", 1.0, 3.0)
CENTRE = FreeParameter("contact_impulse", "force_n", 0.01, 10.0, spread=(0.8, 1.25))
"""A centre whose spread is even in log, so it is the range's geometric centre."""


def _with_force(force_n):
    data = yaml.safe_load(load_scene("tap_rod30_nuskin").path.read_text())
    data["effects"][0]["contact_impulse"]["force_n"] = force_n
    return scene_from_dict(data, "force")


def test_with_values_writes_scalars_and_ranges_and_start_values_reads_them_back() -> None:
    scene = _with_force(1.0)
    fitted = with_values(scene, (FORCE, DAMPING), [0.4, 0.05])
    assert _params(fitted, "contact_impulse")["force_n"] == [0.2, 1.0]  # a scalar: the spread
    assert _params(fitted, "beam_modes")["grasp_damping_ratio"] == 0.05
    assert start_values(fitted, (FORCE, DAMPING)) == pytest.approx([0.4, 0.05])
    # the scene it came from is untouched
    assert _params(scene, "contact_impulse")["force_n"] == 1.0


def test_a_range_keeps_its_width_as_its_centre_moves() -> None:
    fitted = with_values(_with_force([0.5, 2.0]), (FORCE,), [0.4])
    low, high = _params(fitted, "contact_impulse")["force_n"]
    assert high / low == pytest.approx(4.0, rel=1e-5)  # not the spread's 5
    assert start_values(fitted, (FORCE, WIDTH)) == pytest.approx([0.4, 2.0], rel=1e-5)


def test_a_parameter_without_a_spread_writes_a_scalar_over_a_range() -> None:
    silenced = FreeParameter("contact_impulse", "force_n", 0.0, 0.0)  # the noise stage's
    fitted = with_values(_with_force([0.5, 2.0]), (silenced,), [0.0])
    assert _params(fitted, "contact_impulse")["force_n"] == 0.0


def test_a_range_from_zero_is_written_at_the_spread() -> None:
    fitted = with_values(_with_force([0.0, 2.0]), (CENTRE,), [0.4])
    assert _params(fitted, "contact_impulse")["force_n"] == pytest.approx([0.32, 0.5])


def test_a_width_keeps_its_ranges_centre_and_commutes_with_the_centre() -> None:
    scene = _with_force([0.5, 2.0])
    widened = with_values(scene, (WIDTH,), [4.0])
    assert _params(widened, "contact_impulse")["force_n"] == pytest.approx([0.25, 4.0])
    one = with_values(scene, (CENTRE, WIDTH), [0.4, 1.5])
    other = with_values(scene, (WIDTH, CENTRE), [1.5, 0.4])
    assert _params(one, "contact_impulse")["force_n"] == pytest.approx([0.4 / 1.5, 0.6], 1e-5)
    assert _params(other, "contact_impulse")["force_n"] == pytest.approx([0.4 / 1.5, 0.6], 1e-5)
    assert start_values(_with_force(0.7), (WIDTH,)) == [1.0]  # a scalar is a point


def test_a_width_of_a_range_that_is_not_positive_is_refused_by_name() -> None:
    with pytest.raises(SceneError, match=r"'contact_impulse\.force_n\.width' needs a positive"):
        start_values(_with_force([0.0, 1.0]), (WIDTH,))
    with pytest.raises(SceneError, match="needs a positive range"):
        with_values(_with_force([0.0, 1.0]), (WIDTH,), [2.0])


def test_start_values_fall_back_to_the_effects_defaults_and_stay_in_bounds() -> None:
    scene = load_scene("tap_rod30_nuskin_wire")  # grasp_transfer without parameters
    strip = FreeParameter("grasp_transfer", "strip_sigma_m", 0.0005, 0.004)
    share = FreeParameter("grasp_transfer", "finger_load_share", 0.01, 0.6)
    assert start_values(scene, (strip, share)) == pytest.approx([0.0015, 0.01])


def test_a_range_read_as_a_scalar_is_refused_by_name() -> None:
    share = FreeParameter("grasp_transfer", "finger_load_share", 0.01, 0.6)  # no spread
    with pytest.raises(SceneError, match=r"'grasp_transfer\.finger_load_share' is a range"):
        start_values(load_scene("tap_rod30_nuskin"), (share,))


def test_a_parameter_of_an_effect_the_scene_lacks_is_refused() -> None:
    scene = load_scene("handover_rod_nuskin")
    with pytest.raises(SceneError, match="no effect 'contact_impulse'"):
        with_values(scene, (FORCE,), [1.0])


def test_target_misses_are_in_tolerance_units() -> None:
    assert Target("share", 0.2, 0.05).miss(0.3) == pytest.approx(2.0)
    assert Target("events", 1000.0, math.log(1.4), log=True).miss(1400.0) == pytest.approx(1.0)
    assert Target("events", 1000.0, math.log(1.4), log=True).miss(0.0) == math.inf


def test_the_search_finds_a_known_optimum_inside_bounds_and_is_repeatable() -> None:
    scene = load_scene("tap_rod30_nuskin")
    calls = []

    def measure(candidate):
        force = start_values(candidate, (FORCE,))[0]
        damping = start_values(candidate, (DAMPING,))[0]
        calls.append((force, damping))
        # statistics that the true values 0.7 N and 0.012 give exactly
        return {"a": math.log(force / 0.7), "b": math.log(damping / 0.012)}

    targets = (Target("a", 0.0, 0.05), Target("b", 0.0, 0.05))
    values, history = fit(scene, (FORCE, DAMPING), targets, measure, max_evaluations=200)
    assert values[0] == pytest.approx(0.7, rel=0.06)
    assert values[1] == pytest.approx(0.012, rel=0.06)
    assert history[-1].loss <= history[0].loss
    assert all(0.01 <= f <= 10.0 and 0.001 <= d <= 0.2 for f, d in calls)
    again, _ = fit(scene, (FORCE, DAMPING), targets, measure, max_evaluations=200)
    assert again == values


def test_the_search_stops_at_its_budget() -> None:
    scene = load_scene("tap_rod30_nuskin")
    _, history = fit(
        scene, (FORCE,), (Target("a", 5.0, 0.1),), lambda s: {"a": 0.0}, max_evaluations=7
    )
    assert len(history) == 7


def test_effect_lines_read_back_as_the_same_effects() -> None:
    scene = with_values(load_scene("tap_rod30_nuskin"), (FORCE, DAMPING), [0.4, 0.05])
    text = "effects:\n" + "\n".join(effect_lines(scene)) + "\n"
    data = {**yaml.safe_load(scene.path.read_text()), **yaml.safe_load(text)}
    assert scene_from_dict(data, "again").effects == scene.effects


def test_a_stage_of_another_task_is_refused_before_reading_anything() -> None:
    with pytest.raises(SceneError, match=r"calibrates the stages \('noise', 'taps'\)"):
        calibrate_scene(load_scene("tap_rod30_nuskin"), ["/nonexistent"], ("food",))


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["tap_rod30_nuskin", "--real", "/nonexistent"], "does not exist"),
        (["tap_rod30_nuskin", "--real", "/tmp", "--stages", "food"], "calibrates the stages"),
        (["handover_rod_nuskin", "--real", "/tmp"], "has no real captures"),
        (["tap_rod30_nuskin", "--real", "/tmp", "--evaluations", "0"], "--evaluations"),
        (["tap_rod30_nuskin", "--real", "/tmp", "--hold", "beam_modes.x"], "Cannot hold"),
    ],
)
def test_the_command_refuses_bad_input_in_one_line(argv, message, capsys) -> None:
    import argparse

    from ext_sense_sim import cli

    parser = argparse.ArgumentParser()
    cli.register(parser.add_subparsers())
    args = parser.parse_args(["sim", "calibrate", *argv])
    assert args.func(args) == 2
    err = capsys.readouterr().err
    assert message in err
    assert err.count("\n") == 1
    assert "Traceback" not in err


def test_window_medians_add_how_varied_all_events_and_the_busiest_taxels_events_are() -> None:
    stats = {
        "events": np.array([1000.0, 2000.0, 3000.0, 4000.0, 5000.0]),
        "busiest_10": np.array([0.5, 0.25, 1 / 6, 0.125, 0.1]),  # 500 events each time
    }
    medians = window_medians(stats)
    assert medians["events"] == 3000.0
    assert medians["events_p75_over_p25"] == pytest.approx(4000.0 / 2000.0)
    assert medians["busiest_10_events_p75_over_p25"] == pytest.approx(1.0)
    assert "busiest_10_events_p75_over_p25" in TAP_TOLERANCES


def test_a_held_parameter_keeps_the_scenes_value_while_the_others_fit(monkeypatch) -> None:
    import ext_sense_sim.calibration as calibration

    def measure(trials, seed, real):
        return lambda scene: {
            "force": start_values(scene, (FORCE,))[0],
            "damping": start_values(scene, (DAMPING,))[0],
        }

    stage = Stage(
        (FORCE, DAMPING),
        {"force": (0.1, False), "damping": (0.01, False)},
        measure,
        lambda captures: {"force": 2.0, "damping": 0.1},
        1,
    )
    monkeypatch.setitem(calibration.STAGES, "taps", stage)
    monkeypatch.setattr(calibration, "read_sessions", lambda scene, real: [])
    scene = load_scene("tap_rod30_nuskin")
    held = start_values(scene, (DAMPING,))[0]
    text = calibrate_scene(scene, [], ("taps",), hold=(DAMPING.name,), log=lambda line: None)
    fitted = scene_from_dict(yaml.safe_load(text), "fitted")
    assert start_values(fitted, (DAMPING,))[0] == pytest.approx(held)
    assert start_values(fitted, (FORCE,))[0] == pytest.approx(2.0, rel=0.05)


def test_holding_a_parameter_no_stage_frees_is_refused_before_reading_anything() -> None:
    with pytest.raises(SceneError, match=r"Cannot hold \['beam_modes.rod_damping'\]"):
        calibrate_scene(
            load_scene("tap_rod30_nuskin"), ["/nonexistent"], hold=("beam_modes.rod_damping",)
        )


@pytest.mark.parametrize("end", ["low", "high"])
def test_the_tap_stage_bounds_are_values_the_effects_accept(end) -> None:
    from ext_sense_sim.calibration.stages import TAP_FREE
    from ext_sense_sim.fidelity.captures import simulate

    scene = load_scene("tap_rod30_nuskin")
    at_end = with_values(scene, TAP_FREE, [getattr(p, end) for p in TAP_FREE])
    assert len(simulate(at_end, 1, seed=3).captures) == 1  # raises SceneError when refused
