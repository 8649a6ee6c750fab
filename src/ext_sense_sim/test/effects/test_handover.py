import numpy as np
import pytest

from ext_sense_sim.effects.handover import settling, stick_slip


def test_stick_slip_period_is_the_spring_block_answer():
    t = np.arange(0, 1.0, 1e-5)
    normal, mu_s, mu_k, k, v = 3.0, 0.8, 0.4, 1000.0, 0.05
    force, slips = stick_slip(t, normal, mu_s, mu_k, k, v, np.zeros(100))
    assert np.diff(slips[:5]) == pytest.approx([(mu_s - mu_k) * normal / (k * v)] * 4)
    assert force.max() <= mu_s * normal + 1e-9
    assert force[t > slips[0] + 1e-4].min() >= mu_k * normal - 1e-9


def test_settling_reaches_its_final_force():
    t = np.linspace(-0.1, 2.0, 10000)
    f = settling(t, 3.0, 5.0, 0.6)
    assert np.all(f[t < 0] == 0)
    assert f[-1] == pytest.approx(3.0, rel=1e-3)
    assert f.max() < 3.0 * 1.1  # zeta 0.6 overshoots under 10 %
