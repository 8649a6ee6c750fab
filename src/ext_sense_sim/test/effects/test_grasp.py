import numpy as np
import pytest

from ext_sense_sim.effects.grasp import lattice


def test_lattice_is_row_major_8_by_5():
    u, c = lattice(0.003)
    assert u.shape == c.shape == (40,)
    assert np.unique(u).size == 8
    assert np.unique(c).size == 5
    assert u[5] - u[0] == pytest.approx(0.003)
    assert c[1] - c[0] == pytest.approx(0.003)


def test_torque_loads_the_two_pads_with_opposite_sign_and_shear_with_the_same():
    from ext_sense_sim.effects.grasp import GraspTransfer
    from ext_sense_sim.scene import load_scene

    grasp = GraspTransfer({"gain_spread": 0.0}, load_scene("tap_rod30_nuskin"))
    w = grasp.weights(np.full((1, 2), 0.001), np.random.default_rng(0), 1)[0]
    left, right = w[:40], w[40:]
    np.testing.assert_allclose(left[:, 6], -right[:, 6])  # torque: opposite
    np.testing.assert_allclose(left[:, 3], right[:, 3])  # shear along the pads: same
    np.testing.assert_allclose(left[:, 1], -right[:, 1])  # load toward the pads: opposite
    assert np.abs(left[:, 6]).max() > 0
