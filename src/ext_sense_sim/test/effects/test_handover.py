import numpy as np
import pytest

from ext_sense_sim.effects.base import Signals, TimeBase
from ext_sense_sim.effects.handover import HumanGrasp, settling, stick_slip, tremor
from ext_sense_sim.scene import load_scene


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


def test_tremor_is_unit_rms_noise_about_its_frequency():
    rate = 2000.0
    noise = tremor(20_000, rate, np.array([8.0, 12.0]), 2.0, np.random.default_rng(3))
    assert noise.shape == (2, 20_000)
    assert np.sqrt(np.mean(noise**2, axis=1)) == pytest.approx([1.0, 1.0], rel=0.1)
    freqs = np.fft.rfftfreq(noise.shape[1], 1 / rate)
    power = np.abs(np.fft.rfft(noise, axis=1)) ** 2
    band = np.array(
        [power[i, (freqs > f / 2) & (freqs < 2 * f)].sum() for i, f in enumerate([8.0, 12.0])]
    )
    assert np.all(band / power.sum(axis=1) > 0.6)  # most of the power within an octave


def _grasp_forces(params: dict) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    grasp = HumanGrasp(params, load_scene("handover_box_nuskin"))
    time = TimeBase(rate_hz=4000.0, n_samples=1200, n_trials=40)
    signals = Signals()
    grasp.run(signals, time, np.random.default_rng(5))
    contact, labels = signals["contact"], signals["labels"]
    return contact.force_n, contact.force_axial, labels.class_label == "stable"


def test_a_stable_hold_trembles_by_a_share_of_the_force_it_holds():
    across, along, stable = _grasp_forces({"tremor_fraction": 0.03, "p_stable": 1.0})
    assert stable.all()
    late = slice(800, None)  # 200-300 ms: settled, the touch long over
    quiet_across, quiet_along, _ = _grasp_forces({"tremor_fraction": 0.0, "p_stable": 1.0})
    assert np.abs(quiet_across[:, late]).max() == 0.0  # without it a settled hold is still
    held = quiet_along[:, late].mean(axis=1)
    shake = across[:, late].std(axis=1)
    assert np.median(shake / held) == pytest.approx(0.03, rel=0.35)
    assert np.median((along - quiet_along)[:, late].std(axis=1) / held) == pytest.approx(
        0.03, rel=0.35
    )
