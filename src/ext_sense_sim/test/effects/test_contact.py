import numpy as np
import pytest

from ext_sense_sim.effects.contact import half_sine_bins


@pytest.mark.parametrize("duration", [1e-5, 5e-4, 3e-3])
def test_half_sine_impulse_is_exact(duration):
    peak = np.array([3.0])
    f = half_sine_bins(peak, np.array([duration]), np.array([0.01234567]), 16000.0, 800)
    assert f.sum() / 16000 == pytest.approx(2 * 3.0 * duration / np.pi, rel=1e-9)
    assert f.max() <= 3.0 + 1e-12
