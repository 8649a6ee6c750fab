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
