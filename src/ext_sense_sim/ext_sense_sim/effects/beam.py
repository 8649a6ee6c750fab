"""Euler-Bernoulli bending modes of the held object, clamped at the grasp and free at the tip.

Model. The free span (length ``L`` beyond the pads' edge) is a uniform clamped-free beam; its
natural frequencies are ``omega_n = (beta_n L)^2 / L^2 * sqrt(E I / (rho A))`` with ``beta_n L``
the roots of ``1 + cos(x) cosh(x) = 0``, its mode shapes mass-normalised. A force ``F(t)``
across the beam at ``x = a`` drives each mode through its shape there,
``q_n'' + 2 zeta_n omega_n q_n' + omega_n^2 q_n = phi_n(a) F(t)``: the tap position sets the
modes' relative excitation, which carries the position to the grasp. Each mode is integrated
exactly for a force held over each sample (zero-order hold: unconditionally stable).

The beam loads the pads with the root shear ``V = -E I w'''(0)`` and moment ``M = E I w''(0)``,
in both bending planes; the modes above ``max_freq_hz`` are added back quasi-statically (the
mode-acceleration method), so a slow force gives exactly ``V = F`` and ``M = F a``. Damping:
``zeta_n = eta / 2 + grasp_damping_ratio`` (material loss plus the soft pads) unless the scene
sets ``damping_ratio`` (scalar or one per mode).
"""

from __future__ import annotations

import math
from typing import Any, ClassVar

import numpy as np
import scipy.linalg
from scipy.optimize import brentq
from scipy.signal import lfilter

from ext_sense_sim.effects.base import Effect, Signals, TimeBase
from ext_sense_sim.errors import SceneError

_ASYMPTOTIC_FROM = 12


def clamped_free_roots(n_modes: int) -> np.ndarray:
    """The first roots ``beta_n L`` of ``1 + cos(x) cosh(x) = 0``, solved without overflow."""
    roots = np.empty(n_modes)
    for i in range(n_modes):
        n = i + 1
        if n >= _ASYMPTOTIC_FROM:
            roots[i] = (2 * n - 1) * math.pi / 2
            continue
        roots[i] = brentq(
            lambda x: math.cos(x) + 1.0 / math.cosh(x), (n - 1) * math.pi, n * math.pi, xtol=1e-14
        )
    return roots


def mode_shapes(beta_l: np.ndarray, x_over_l: np.ndarray) -> np.ndarray:
    """Clamped-free mode shapes with unit mean square, ``S + (n_modes,)`` at positions ``S``.

    ``phi = e^{-bx} + (1 - sigma) sinh(bx) - cos(bx) + sigma sin(bx)``, the sinh term written as
    ratios of decaying exponentials, so high modes and long beams stay finite.
    """
    bl = np.asarray(beta_l, dtype=np.float64)
    bx = np.asarray(x_over_l, dtype=np.float64)[..., None] * bl
    decay = np.exp(-bl)
    # (sinh bL + sin bL) / sinh bL, and sigma = (cosh bL + cos bL) / (sinh bL + sin bL)
    denom = 1.0 + np.sin(bl) * 2.0 * decay / (1.0 - decay**2)
    sigma = _sigma(bl)
    # (1 - sigma) sinh(bx) = (sin bL - cos bL - e^{-bL}) / denom * sinh(bx) / sinh(bL), with
    # sinh(bx) / sinh(bL) = (e^{b(x-L)} - e^{-b(x+L)}) / (1 - e^{-2bL})
    ratio = (np.exp(bx - bl) - np.exp(-bx - bl)) / (1.0 - decay**2)
    tail = (np.sin(bl) - np.cos(bl) - decay) / denom * ratio
    return np.exp(-bx) + tail - np.cos(bx) + sigma * np.sin(bx)


def root_derivatives(beta_l: np.ndarray, length: float) -> tuple[np.ndarray, np.ndarray]:
    """``phi_n''(0)`` and ``phi_n'''(0)`` of the unit-mean-square shapes (per metre^2, ^3)."""
    b = np.asarray(beta_l) / length
    return 2.0 * b**2, -2.0 * _sigma(np.asarray(beta_l)) * b**3


def _sigma(bl: np.ndarray) -> np.ndarray:
    """``(cosh bL + cos bL) / (sinh bL + sin bL)`` without overflow (tends to 1)."""
    decay = np.exp(-bl)
    return (1.0 + decay**2 + 2.0 * np.cos(bl) * decay) / (1.0 - decay**2 + 2.0 * np.sin(bl) * decay)


def zoh_filters(omega: np.ndarray, zeta: np.ndarray, dt: float) -> tuple[np.ndarray, ...]:
    """Exact zero-order-hold discretisation of ``q'' + 2 zeta w q' + w^2 q = f``.

    Returns ``(b_q, b_v, a)``, each ``(n_modes, 3)``: the numerators giving displacement and
    velocity from the force, and their shared denominator.
    """
    n = len(omega)
    b_q, b_v, a = np.zeros((n, 3)), np.zeros((n, 3)), np.zeros((n, 3))
    for i, (w, z) in enumerate(zip(omega, zeta, strict=True)):
        big = np.zeros((3, 3))
        big[0, 1] = 1.0
        big[1, 0], big[1, 1], big[1, 2] = -(w**2), -2.0 * z * w, 1.0
        e = scipy.linalg.expm(big * dt)
        ad, (b1, b2) = e[:2, :2].copy(), e[:2, 2]
        # transfer functions of the 2x2 state space: (C adj(zI - A) B) / det(zI - A)
        a[i] = [1.0, -np.trace(ad), np.linalg.det(ad)]
        (a11, a12), (a21, a22) = ad
        b_q[i] = [0.0, b1, a12 * b2 - a22 * b1]
        b_v[i] = [0.0, b2, a21 * b1 - a11 * b2]
    return b_q, b_v, a


class BeamModel:
    """One bending plane of a clamped-free beam (SI units), its modes below ``max_freq_hz``."""

    def __init__(
        self,
        length_m: float,
        youngs_pa: float,
        inertia_m4: float,
        density: float,
        area_m2: float,
        zeta: float | np.ndarray,
        max_freq_hz: float,
        max_modes: int = 60,
    ) -> None:
        self.length = float(length_m)
        self.ei = youngs_pa * inertia_m4
        self.mass_per_m = density * area_m2
        scale = math.sqrt(self.ei / self.mass_per_m) / self.length**2
        roots = clamped_free_roots(max_modes)
        omega = roots**2 * scale
        keep = max(1, int(np.searchsorted(omega, 2 * math.pi * max_freq_hz)))
        self.beta_l = roots[:keep]
        self.omega = omega[:keep]
        self.zeta = np.broadcast_to(np.asarray(zeta, dtype=np.float64), (keep,)).copy()
        self.norm = 1.0 / math.sqrt(self.mass_per_m * self.length)  # mass normalisation
        d2, d3 = root_derivatives(self.beta_l, self.length)
        self.shear_coef = -self.ei * d3 * self.norm  # V = sum shear_coef * phi(a) * norm * g
        self.moment_coef = self.ei * d2 * self.norm

    @property
    def freqs_hz(self) -> np.ndarray:
        """Natural frequencies of the kept modes, Hz."""
        return self.omega / (2 * math.pi)

    def shapes_at(self, position_m: np.ndarray) -> np.ndarray:
        """Mass-normalised shapes at positions, ``(n_positions, n_modes)``."""
        return mode_shapes(self.beta_l, np.asarray(position_m) / self.length) * self.norm

    def static_residual(self, position_m: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Shear and moment the kept modes miss for a static unit force at ``position_m``."""
        phi = self.shapes_at(position_m)
        v_modal = phi @ (self.shear_coef / self.omega**2)
        m_modal = phi @ (self.moment_coef / self.omega**2)
        return 1.0 - v_modal, np.asarray(position_m) - m_modal

    def root_loads(
        self, force: np.ndarray, position_m: np.ndarray, dt: float
    ) -> tuple[np.ndarray, np.ndarray]:
        """Root shear and moment of ``force`` ``(n_trials, n_samples)`` at ``position_m``."""
        b_q, _, a = zoh_filters(self.omega, self.zeta, dt)
        phi = self.shapes_at(position_m)  # (n_trials, n_modes)
        shear = np.zeros_like(force)
        moment = np.zeros_like(force)
        for i in range(len(self.omega)):
            g = lfilter(b_q[i], a[i], force, axis=-1)
            shear += (self.shear_coef[i] * phi[:, i])[:, None] * g
            moment += (self.moment_coef[i] * phi[:, i])[:, None] * g
        r_v, r_m = self.static_residual(position_m)
        shear += r_v[:, None] * force
        moment += r_m[:, None] * force
        return shear, moment

    def modal_states(
        self, force: np.ndarray, position_m: np.ndarray, dt: float
    ) -> tuple[np.ndarray, np.ndarray]:
        """Modal displacements and velocities, each ``(n_trials, n_modes, n_samples)``."""
        b_q, b_v, a = zoh_filters(self.omega, self.zeta, dt)
        phi = self.shapes_at(position_m)
        q = np.empty((force.shape[0], len(self.omega), force.shape[1]))
        v = np.empty_like(q)
        for i in range(len(self.omega)):
            drive = phi[:, i : i + 1] * force
            q[:, i] = lfilter(b_q[i], a[i], drive, axis=-1)
            v[:, i] = lfilter(b_v[i], a[i], drive, axis=-1)
        return q, v

    def energy(self, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """Total modal energy ``sum (v^2 + omega^2 q^2) / 2``, joules, ``(n_trials, n_samples)``."""
        return 0.5 * np.sum(v**2 + (self.omega[None, :, None] * q) ** 2, axis=1)


class TorsionModel:
    """Torsion modes of a clamped-free uniform shaft of circular section (SI arguments).

    ``theta_n(x) = sin((2n - 1) pi x / (2 L))``, ``omega_n = (2n - 1) pi / (2 L) sqrt(G / rho)``,
    mass-normalised with ``rho J``. A torque at ``a`` drives mode n by ``theta_n(a)``; the root
    torque is ``G J theta'(0)``, with the truncated modes added back quasi-statically.
    """

    def __init__(
        self,
        length_m: float,
        shear_modulus_pa: float,
        polar_m4: float,
        density: float,
        zeta: float,
        max_freq_hz: float,
    ) -> None:
        self.length = float(length_m)
        self.gj = shear_modulus_pa * polar_m4
        k = (2 * np.arange(1, 200) - 1) * math.pi / (2 * self.length)
        omega = k * math.sqrt(shear_modulus_pa / density)
        keep = max(1, int(np.searchsorted(omega, 2 * math.pi * max_freq_hz)))
        self.k, self.omega = k[:keep], omega[:keep]
        self.zeta = np.full(keep, float(zeta))
        self.norm = math.sqrt(2.0 / (density * polar_m4 * self.length))
        self.torque_coef = self.gj * self.k * self.norm  # root torque per modal coordinate

    @property
    def freqs_hz(self) -> np.ndarray:
        """Natural frequencies of the kept modes, Hz."""
        return self.omega / (2 * math.pi)

    def root_torque(self, torque: np.ndarray, position_m: np.ndarray, dt: float) -> np.ndarray:
        """Root torque ``(n_trials, n_samples)`` N m for torques applied at positions."""
        b_q, _, a = zoh_filters(self.omega, self.zeta, dt)
        shape = np.sin(np.asarray(position_m)[:, None] * self.k) * self.norm  # (n, modes)
        out = np.zeros_like(torque)
        for i in range(len(self.omega)):
            g = lfilter(b_q[i], a[i], torque, axis=-1)
            out += (self.torque_coef[i] * shape[:, i])[:, None] * g
        residual = 1.0 - shape @ (self.torque_coef / self.omega**2)
        return out + residual[:, None] * torque


class BeamModes(Effect):
    """Clamped-free Euler-Bernoulli modes of the held object (see module docstring).

    Gives ``clamp_load`` ``(n_trials, 6, n_samples)``: shear and moment toward the pads, shear
    and moment along them, axial force, torque about the object's axis. ``torsion: true``
    (round rods struck on their surface) drives the :class:`TorsionModel` with the torque of
    the tap's component along the pads one radius off the axis.
    """

    name = "beam_modes"
    needs = ("contact",)
    gives = ("clamp_load",)
    defaults: ClassVar[dict[str, Any]] = {
        "max_freq_hz": 6000.0,
        "max_modes": 40,
        "damping_ratio": None,
        "grasp_damping_ratio": 0.03,
        "torsion": False,
        "poisson_ratio": 0.35,
    }

    def setup(self) -> None:
        """Check the parameters and precompute what every batch shares."""
        g = self.context.geometry
        max_modes = int(self.scalar("max_modes", 1, 10_000))
        max_freq = self.scalar("max_freq_hz", 1.0, 1e7)
        zeta = self.params["damping_ratio"]
        if zeta is None:  # material loss plus the lossy soft pads of the grasp
            zeta = g.material.loss_factor / 2 + self.scalar("grasp_damping_ratio", 0.0, 10.0)
        zeta = np.asarray(zeta, dtype=np.float64)
        if not np.all(np.isfinite(zeta)) or np.any(zeta < 0):
            raise SceneError(
                f"Effect '{self.name}': 'damping_ratio' must be >= 0 and finite. Got {zeta!r}."
            )
        common = (g.free_length_m, g.material.youngs_pa)
        rest = (g.material.density, g.area_m2)
        self.normal = BeamModel(*common, g.inertia_normal_m4, *rest, zeta, max_freq, max_modes)
        self.tangent = BeamModel(*common, g.inertia_tangent_m4, *rest, zeta, max_freq, max_modes)
        self.torsion: TorsionModel | None = None
        if bool(self.params["torsion"]):
            nu = self.scalar("poisson_ratio", 0.0, 0.5)
            shear = g.material.youngs_pa / (2.0 * (1.0 + nu))
            polar = g.inertia_normal_m4 + g.inertia_tangent_m4
            zeta_t = float(np.atleast_1d(zeta)[0])
            self.torsion = TorsionModel(
                g.free_length_m, shear, polar, g.material.density, zeta_t, max_freq
            )
            self.radius = math.sqrt(g.area_m2 / math.pi)

    def run(self, signals: Signals, time: TimeBase, rng: np.random.Generator) -> None:
        """Give ``clamp_load`` from ``contact``."""
        contact = signals.need("contact", self.name)
        x = np.clip(contact.position_m, 0.0, self.normal.length)
        f_n = contact.force_n * np.cos(contact.angle_rad)[:, None]
        f_t = contact.force_n * np.sin(contact.angle_rad)[:, None]
        load = np.zeros((time.n_trials, 6, time.n_samples))
        load[:, 0], load[:, 1] = self.normal.root_loads(f_n, x, time.dt)
        if np.any(f_t != 0):
            load[:, 2], load[:, 3] = self.tangent.root_loads(f_t, x, time.dt)
        else:
            load[:, 2:4] = 0.0
        load[:, 4] = contact.force_axial
        if self.torsion is not None and np.any(f_t != 0):
            load[:, 5] = self.torsion.root_torque(f_t * self.radius, x, time.dt)
        signals["clamp_load"] = load
