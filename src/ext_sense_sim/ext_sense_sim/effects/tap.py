"""Contact impulse: a tap on the held rod.

Model: a half-sine force pulse of peak ``force_n`` and length ``duration_s`` across the rod at a
random position (the label) and ``angle_deg`` from the pad normal; the contact time decides how
hard the upper modes ring (little above ``1 / tau``). ``impact_force_n`` (default 0) adds a
short half-sine of ``impact_duration_s`` at the same onset: a fingertip's nail and bone striking
before the pulp's longer push. With ``moment_exponent`` g the force of a tap at ``x`` from
the grasp is scaled by ``(s / 2x)^g`` (``s`` the free span): a force held fixed loads the grasp
in proportion to its lever arm, while the real taps' event counts hardly vary (the tap force
itself was not recorded); g is fitted to that spread. The scenes' values and their fit:
docs/simulator.md.
"""

from __future__ import annotations

from typing import Any, ClassVar

import numpy as np

from ext_sense_sim.effects.base import Effect, Signals, TimeBase
from ext_sense_sim.effects.contact import Contact, Labels, half_sine_bins
from ext_sense_sim.errors import SceneError


class ContactImpulse(Effect):
    """Half-sine tap at a random position of the free span (see module docstring)."""

    name = "contact_impulse"
    gives = ("contact", "labels")
    defaults: ClassVar[dict[str, Any]] = {
        "force_n": [1.0, 5.0],
        "duration_s": [0.0005, 0.003],
        "onset_s": [0.045, 0.055],
        "angle_deg": [-30.0, 30.0],
        "margin_m": 0.01,
        "impact_force_n": 0.0,
        "impact_duration_s": [0.0005, 0.002],
        "moment_exponent": 0.0,
    }

    def setup(self) -> None:
        """Check the parameters and precompute what every batch shares."""
        geometry = self.context.geometry
        if geometry.free_length_m <= 2 * self.scalar("margin_m", 0.0):
            raise SceneError(
                f"Effect '{self.name}': the free span ({geometry.free_length_m} m) must be longer "
                f"than twice 'margin_m' ({self.params['margin_m']} m)."
            )

    def run(self, signals: Signals, time: TimeBase, rng: np.random.Generator) -> None:
        """Give ``contact`` (one half-sine per trial) and ``labels`` (tap position)."""
        n = time.n_trials
        g = self.context.geometry
        margin = self.scalar("margin_m")
        xi = rng.uniform(margin, g.free_length_m - margin, size=n)
        peak = self.draw("force_n", rng, n, 0.0)
        tau = self.draw("duration_s", rng, n, 1e-6, 1.0)
        onset = self.draw("onset_s", rng, n, 0.0, time.n_samples * time.dt)
        force = half_sine_bins(peak, tau, onset, time.rate_hz, time.n_samples)
        angle = np.deg2rad(self.draw("angle_deg", rng, n, -90.0, 90.0))
        if self.params["impact_force_n"] != 0.0:  # drawn only when asked: other streams stay
            impact = self.draw("impact_force_n", rng, n, 0.0)
            short = self.draw("impact_duration_s", rng, n, 1e-6, 1.0)
            force += half_sine_bins(impact, short, onset, time.rate_hz, time.n_samples)
        exponent = self.scalar("moment_exponent", 0.0, 3.0)
        if exponent:
            force *= ((g.free_length_m / 2) / xi)[:, None] ** exponent
        signals["contact"] = Contact(force, np.zeros_like(force), xi, angle)
        signals["labels"] = Labels(
            onset_ns=np.round(onset * 1e9).astype(np.int64),
            y_m=g.held_length_m + xi,
            class_label=np.full(n, "", dtype="<U1"),
        )
