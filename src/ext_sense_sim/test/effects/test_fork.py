import numpy as np
import pytest

from ext_sense_sim.effects.fork import FOODS, penetration_force


def test_water_forces_are_tiny_and_apple_fractures():
    depth = np.linspace(-0.005, 0.03, 5000)
    water = penetration_force(depth, FOODS["water"], np.zeros(0), 0.0)
    assert 0 < water.max() < 0.01
    apple = penetration_force(depth, FOODS["apple"], np.zeros(0), 0.0)
    assert apple.max() == pytest.approx(FOODS["apple"].fracture_n, rel=0.02)
    assert apple[-1] == pytest.approx(FOODS["apple"].cut_n)
    assert np.all(penetration_force(depth, FOODS["empty"], np.zeros(0), 0.0) == 0)


def _skewers(**params):
    """Apple, watermelon and water skewered with the food scene's arm (``fork_penetration``)."""
    from ext_sense_sim.effects.base import Signals, TimeBase
    from ext_sense_sim.effects.fork import ForkPenetration
    from ext_sense_sim.scene import load_scene

    fork = ForkPenetration(
        {"foods": ["apple", "watermelon", "water"], "spread": 0.0, "angle_deg": 0.0, **params},
        load_scene("food_fork_nuskin"),
    )
    time = TimeBase(rate_hz=1000.0, n_samples=4000, n_trials=3)
    signals = Signals()
    fork.run(signals, time, np.random.default_rng(0))
    contact = signals["contact"]
    return np.hypot(contact.force_n, contact.force_axial), signals["motion"], time.t()


def test_each_food_is_touched_at_its_gap_and_apple_stops_the_arm_on_the_collision():
    force, motion, t = _skewers(onset_s=0.5, travel_m=0.027, stop_n=7.3, gap_jitter_m=0.0)
    touched = [t[np.argmax(f > 0)] - 0.5 for f in force[:2]]
    for seconds, food in zip(touched, ("apple", "watermelon"), strict=True):
        assert seconds == pytest.approx(FOODS[food].gap_m / 0.01, abs=0.01)  # 1 cm/s
    assert motion.stop_s[0] < 0.5 + 0.027 / 0.01 - 0.5  # apple: the 7.3 N collision, early
    assert force[0].max() == pytest.approx(7.3, rel=0.01)
    assert motion.stop_s[2] == pytest.approx(0.5 + 2.7)  # water: the whole travel


def test_the_held_food_relaxes_by_its_share():
    still, motion, t = _skewers(onset_s=0.5, travel_m=0.027, stop_n=7.3, gap_jitter_m=0.0)
    relaxed, _, _ = _skewers(
        onset_s=0.5, travel_m=0.027, stop_n=7.3, gap_jitter_m=0.0, relax_share=0.25, relax_s=0.3
    )
    held = t >= motion.stop_s[0]
    assert np.all(still[0][held] == still[0][held][0])  # no relaxation: the force holds
    assert relaxed[0][-1] == pytest.approx(0.75 * still[0][-1], rel=0.01)
    np.testing.assert_array_equal(relaxed[0][~held], still[0][~held])
