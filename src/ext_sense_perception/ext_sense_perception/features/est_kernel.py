"""The Event Spike Tensor kernel: a small MLP of the lag, fitted without torch (no ROS)."""

from __future__ import annotations

import itertools

import numpy as np


def est_kernel(
    t_s: np.ndarray, weights: list[tuple[np.ndarray, np.ndarray]], slope: float = 0.1
) -> np.ndarray:
    """The EST kernel MLP (1 -> 30 -> 30 -> 1, Leaky ReLU) at lags ``t_s`` seconds, ``(n,)``."""
    h = np.asarray(t_s, dtype=np.float64)[:, None]
    for i, (w, b) in enumerate(weights):
        h = h @ w + b
        if i < len(weights) - 1:
            h = np.where(h > 0, h, slope * h)
    return h[:, 0]


def fit_est_kernel(
    tau_s: float = 0.005, span_s: float = 0.05, seed: int = 0
) -> list[tuple[np.ndarray, np.ndarray]]:
    """Weights (three ``(W, b)`` layers) of the EST kernel MLP, fitted to ``exp(-t / tau)``.

    The paper learns the kernel end to end with torch; here it is fitted to the exponential EST's
    authors start from, keeping the parameterisation but not the task-specific learning. Lags
    0..``span_s`` seconds are fitted.
    """
    rng = np.random.default_rng(seed)
    sizes = [1, 30, 30, 1]
    weights = [
        (rng.normal(0, np.sqrt(2.0 / a), (a, b)), np.zeros(b)) for a, b in itertools.pairwise(sizes)
    ]
    x = np.linspace(0.0, span_s, 256)[:, None] / span_s
    y = np.exp(-x[:, 0] * span_s / tau_s)[:, None]
    lr, slope = 0.01, 0.1
    m = [(np.zeros_like(w), np.zeros_like(b)) for w, b in weights]
    v = [(np.zeros_like(w), np.zeros_like(b)) for w, b in weights]
    for step in range(1, 1501):  # plain Adam on the mean squared error
        acts, pres = [x], []
        h = x
        for i, (w, b) in enumerate(weights):
            z = h @ w + b
            pres.append(z)
            h = np.where(z > 0, z, slope * z) if i < 2 else z
            acts.append(h)
        g = 2 * (h - y) / len(x)
        for i in range(2, -1, -1):
            if i < 2:
                g = g * np.where(pres[i] > 0, 1.0, slope)
            gw, gb = acts[i].T @ g, g.sum(0)
            g = g @ weights[i][0].T
            mw, mb = m[i]
            vw, vb = v[i]
            mw, mb = 0.9 * mw + 0.1 * gw, 0.9 * mb + 0.1 * gb
            vw, vb = 0.999 * vw + 0.001 * gw**2, 0.999 * vb + 0.001 * gb**2
            m[i], v[i] = (mw, mb), (vw, vb)
            c1, c2 = 1 - 0.9**step, 1 - 0.999**step
            w, b = weights[i]
            weights[i] = (
                w - lr * (mw / c1) / (np.sqrt(vw / c2) + 1e-8),
                b - lr * (mb / c1) / (np.sqrt(vb / c2) + 1e-8),
            )
    # fold the input normalisation (t / span) into the first layer so the kernel takes seconds
    w0, b0 = weights[0]
    weights[0] = (w0 / span_s, b0)
    return weights
