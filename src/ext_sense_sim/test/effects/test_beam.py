import math

import numpy as np
import pytest
import scipy.linalg

from ext_sense_sim.effects.beam import BeamModel, TorsionModel, clamped_free_roots, mode_shapes

ACRYLIC = dict(
    youngs_pa=3.2e9,
    inertia_m4=math.pi * 0.01**4 / 64,
    density=1190.0,
    area_m2=math.pi * 0.01**2 / 4,
)


def fe_cantilever_freqs(length, ei, m, n_el=60):
    """Independent check: Hermite cubic finite elements of a clamped-free beam."""
    le = length / n_el
    k = (
        ei
        / le**3
        * np.array(
            [
                [12, 6 * le, -12, 6 * le],
                [6 * le, 4 * le**2, -6 * le, 2 * le**2],
                [-12, -6 * le, 12, -6 * le],
                [6 * le, 2 * le**2, -6 * le, 4 * le**2],
            ]
        )
    )
    mm = (
        m
        * le
        / 420
        * np.array(
            [
                [156, 22 * le, 54, -13 * le],
                [22 * le, 4 * le**2, 13 * le, -3 * le**2],
                [54, 13 * le, 156, -22 * le],
                [-13 * le, -3 * le**2, -22 * le, 4 * le**2],
            ]
        )
    )
    n = 2 * (n_el + 1)
    kg, mg = np.zeros((n, n)), np.zeros((n, n))
    for e in range(n_el):
        s = slice(2 * e, 2 * e + 4)
        kg[s, s] += k
        mg[s, s] += mm
    w2 = scipy.linalg.eigh(kg[2:, 2:], mg[2:, 2:], eigvals_only=True)
    return np.sqrt(w2) / (2 * math.pi)


def test_roots_match_the_tabulated_values():
    np.testing.assert_allclose(
        clamped_free_roots(5), [1.875104, 4.694091, 7.854757, 10.995541, 14.137168], atol=2e-6
    )


@pytest.mark.parametrize("length", [0.17, 0.27, 0.47])
def test_frequencies_within_half_a_percent_of_finite_elements(length):
    model = BeamModel(length, **ACRYLIC, zeta=0.02, max_freq_hz=6000)
    fe = fe_cantilever_freqs(
        length,
        ACRYLIC["youngs_pa"] * ACRYLIC["inertia_m4"],
        ACRYLIC["density"] * ACRYLIC["area_m2"],
    )
    n = len(model.freqs_hz)
    assert n >= 4
    np.testing.assert_allclose(model.freqs_hz, fe[:n], rtol=0.005)
    # first mode against the closed form 3.516 / (2 pi L^2) sqrt(EI / m)
    ei_m = ACRYLIC["youngs_pa"] * ACRYLIC["inertia_m4"] / (ACRYLIC["density"] * ACRYLIC["area_m2"])
    assert model.freqs_hz[0] == pytest.approx(
        3.5160 / (2 * math.pi * length**2) * math.sqrt(ei_m), rel=1e-4
    )


def test_shapes_are_orthonormal_and_finite_for_many_modes():
    roots = clamped_free_roots(300)
    x = np.linspace(0, 1, 20_001)
    phi = mode_shapes(roots, x)
    assert np.isfinite(phi).all()
    gram = phi[:, :40].T @ phi[:, :40] * (x[1] - x[0])
    np.testing.assert_allclose(gram, np.eye(40), atol=2e-3)
    assert np.abs(phi[0]).max() < 1e-12  # clamped: w(0) = 0


def test_static_loads_are_exact():
    model = BeamModel(0.27, **ACRYLIC, zeta=0.02, max_freq_hz=3000)
    a = np.array([0.03, 0.1, 0.2, 0.27])
    force = np.ones((4, 4000)) * 2.0  # a constant force: after the transient, statics
    shear, moment = model.root_loads(force, a, 1 / 16000)
    # heavily damped check on the mean of the last part (modes still ring a little)
    np.testing.assert_allclose(shear[:, -2000:].mean(axis=1), 2.0, rtol=0.05)
    np.testing.assert_allclose(moment[:, -2000:].mean(axis=1), 2.0 * a, rtol=0.05)
    many = BeamModel(0.27, **ACRYLIC, zeta=0.02, max_freq_hz=1e9, max_modes=2000)
    r_v, r_m = many.static_residual(a)
    assert np.abs(r_v).max() < 2e-3
    assert np.abs(r_m).max() < 1e-6


def test_tap_position_sets_the_modal_excitation():
    model = BeamModel(0.27, **ACRYLIC, zeta=0.02, max_freq_hz=3000)
    phi = model.shapes_at(np.array([0.1, 0.25]))
    ratio = np.abs(phi[:, 1] / phi[:, 0])
    assert not np.isclose(ratio[0], ratio[1], rtol=0.1)


@pytest.mark.parametrize("zeta", [0.0, 1e-4, 0.05, 0.9, 5.0])
def test_energy_decays_and_stays_finite(zeta):
    model = BeamModel(0.47, **ACRYLIC, zeta=zeta, max_freq_hz=1e6, max_modes=200)
    force = np.zeros((1, 16000))
    force[0, 10] = 1e4  # 1 N s over one sample: a huge, short force
    q, v = model.modal_states(force, np.array([0.4]), 1 / 16000)
    energy = model.energy(q, v)[0, 12:]
    assert np.isfinite(energy).all()
    assert np.all(np.diff(energy) <= 1e-9 * energy[0])  # free energy never grows
    if zeta == 0.0:
        np.testing.assert_allclose(energy, energy[0], rtol=1e-6)
    elif zeta >= 1e-4:
        assert energy[-1] < energy[0]


def test_single_mode_decay_rate_matches_damping():
    model = BeamModel(0.27, **ACRYLIC, zeta=0.01, max_freq_hz=40)
    assert len(model.omega) == 1
    force = np.zeros((1, 32000))
    force[0, 0] = 1.0
    q, v = model.modal_states(force, np.array([0.27]), 1 / 16000)
    energy = model.energy(q, v)[0]
    t = np.arange(32000) / 16000
    fit = np.polyfit(t[100:], np.log(energy[100:]), 1)[0]
    assert fit == pytest.approx(-2 * 0.01 * model.omega[0], rel=0.02)


@pytest.mark.parametrize("force", [1e-12, 1e6])
def test_tiny_and_huge_forces_scale_linearly(force):
    model = BeamModel(0.27, **ACRYLIC, zeta=0.02, max_freq_hz=6000)
    f = np.zeros((1, 4800))
    f[0, 100:110] = 1.0
    base = model.root_loads(f, np.array([0.2]), 1 / 16000)[0]
    scaled = model.root_loads(f * force, np.array([0.2]), 1 / 16000)[0]
    assert np.isfinite(scaled).all()
    np.testing.assert_allclose(
        scaled, base * force, rtol=1e-9, atol=1e-9 * np.abs(base).max() * force
    )


def test_long_duration_undamped_stays_bounded():
    model = BeamModel(0.27, **ACRYLIC, zeta=0.0, max_freq_hz=3000)
    n = 16000 * 60  # one minute at 16 kHz
    force = np.zeros((1, n))
    force[0, :8] = 2.0
    q, v = model.modal_states(force, np.array([0.2]), 1 / 16000)
    energy = model.energy(q, v)[0, 10:]
    np.testing.assert_allclose(energy, energy[0], rtol=1e-6)  # no numerical drift in a minute


@pytest.mark.parametrize("youngs", [1e3, 1e12])
def test_extreme_stiffness_stays_finite(youngs):
    params = {**ACRYLIC, "youngs_pa": youngs}
    model = BeamModel(0.27, **params, zeta=0.02, max_freq_hz=6000)
    assert len(model.omega) >= 1
    force = np.zeros((2, 4800))
    force[:, 100:120] = 5.0
    shear, moment = model.root_loads(force, np.array([0.05, 0.27]), 1 / 16000)
    assert np.isfinite(shear).all()
    assert np.isfinite(moment).all()
    # static limit still exact at the end of a long constant push for the stiff beam
    if youngs > 1e9:
        push = np.full((1, 4800), 1.0)
        s2, m2 = model.root_loads(push, np.array([0.2]), 1 / 16000)
        assert s2[0, -1] == pytest.approx(1.0, rel=1e-3)
        assert m2[0, -1] == pytest.approx(0.2, rel=1e-3)


def test_torsion_frequencies_and_static_torque_are_the_shaft_answers():
    g, j, rho, length = 3.2e9 / 2.7, math.pi * 0.01**4 / 32, 1190.0, 0.27
    shaft = TorsionModel(length, g, j, rho, zeta=0.05, max_freq_hz=6000)
    c = math.sqrt(g / rho)
    expected = np.array([1, 3, 5]) * c / (4 * length)  # clamped-free: (2n - 1) c / (4 L)
    np.testing.assert_allclose(shaft.freqs_hz, expected, rtol=1e-12)
    # a slowly applied torque reaches the grasp exactly, wherever it acts
    t = np.linspace(0, 1, 16000)
    torque = np.tile(0.02 * np.minimum(t / 0.5, 1.0), (3, 1))
    root = shaft.root_torque(torque, np.array([0.03, 0.15, 0.26]), 1 / 16000)
    np.testing.assert_allclose(root[:, -1], 0.02, rtol=1e-3)
    # a short twist excites the first mode, which rings at its frequency
    kick = np.zeros((1, 16000))
    kick[0, 10] = 1.0
    ring = shaft.root_torque(kick, np.array([0.2]), 1 / 16000)[0, 100:]
    spectrum = np.abs(np.fft.rfft(ring))
    peak_hz = np.argmax(spectrum) * 16000 / ring.size
    assert abs(peak_hz - expected[0]) < 5
    assert np.all(np.isfinite(ring))
