# ruff: noqa: N803  (X / F for sample matrices, as in scikit-learn)
"""Feature sets computed from contact windows (no ROS).

Every feature set here is a fixed linear map along the time axis of the window (rebinning,
decimation, a DFT, an EST kernel convolution, window sums), followed by at most a few
element-wise steps (magnitude, ``log1p``, ReLU layers of the autoencoder's encoder). That keeps
the NumPy path vectorised and lets :mod:`ext_sense_perception.onnx_export` express the same
pipeline in ONNX, so the deployed model starts from the raw window.

:class:`WindowFeatures` is a scikit-learn transformer whose input is the flattened window
``(n_windows, n_channels * n_samples)`` so it can sit at the head of a ``Pipeline`` and be
tuned inside cross-validation folds (no leakage of the autoencoder's training).

Sampling-rate reduction: BioTac decimation is part of the map (``rate_hz``); the NUSkin
per-taxel refractory drop works on events, before binning: :func:`refractory_mask`.
"""

from __future__ import annotations

import itertools
from enum import IntEnum
from typing import NamedTuple

import numpy as np
from sklearn.base import BaseEstimator, TransformerMixin

from ext_sense_perception.errors import PerceptionError

MS = 1_000_000
FFT_SCALE_IN = 1.0 / 1000.0  # the public code divides the signal by 1000 before the FFT
FFT_SCALE_OUT = 1.0 / 10.0  # ... and the magnitude by 10 after it


class FeatureKind(IntEnum):
    """The feature sets (``name.lower()`` is the CLI / model-card name)."""

    BASELINE = 0  # NUSkin binned signed counts; BioTac raw PAC
    FFT = 1  # |FFT| of each channel's (binned or decimated) series, paper's scaling
    EST = 2  # Event Spike Tensor style kernel convolution, sampled at equally spaced times
    ACTIVITY = 3  # log1p event activity over time (all taxels) and per taxel over the window
    AUTOENCODER = 4  # 32-d code of an MLP autoencoder over the FFT features

    @classmethod
    def parse(cls, value: str | int | FeatureKind) -> FeatureKind:
        """Kind from its name.

        Raises:
            PerceptionError: when the name is unknown.
        """
        if isinstance(value, FeatureKind):
            return value
        if isinstance(value, int):
            return cls(value)
        key = str(value).strip().upper()
        key = {"AE": "AUTOENCODER", "RAW": "BASELINE", "BINNED": "BASELINE", "PAC": "BASELINE"}.get(
            key, key
        )
        try:
            return cls[key]
        except KeyError as err:
            names = ", ".join(k.name.lower() for k in cls)
            raise PerceptionError(
                f"The 'features' parameter must be one of {names}. Got {value!r} instead."
            ) from err


class Geometry(NamedTuple):
    """Shape and timing of the windows a feature pipeline accepts."""

    n_channels: int
    n_samples: int
    period_ns: int
    pre_ns: int
    sensor: str = "nuskin"


def select_channels(selection: str | None, n_channels: int) -> np.ndarray:
    """Row indices of a channel selection.

    Args:
        selection: ``None``/``"all"``, ``"left"`` (taxels 1..40), ``"right"`` (41..80),
            ``"taxel:N"`` (one taxel id, 1-based) or ``"ids:1,2,5"``.
        n_channels: Channels in the window.

    Returns:
        Indices into the channel axis.

    Raises:
        PerceptionError: on an unknown selection or ids out of range.
    """
    if selection is None or selection == "all":
        return np.arange(n_channels)
    half = n_channels // 2
    if selection in ("left", "one_finger"):
        return np.arange(half)
    if selection == "right":
        return np.arange(half, n_channels)
    if selection.startswith(("taxel:", "ids:")):
        try:
            ids = [int(v) for v in selection.split(":", 1)[1].split(",")]
        except ValueError as err:
            raise PerceptionError(
                f"The 'channels' parameter must list integer ids. Got {selection!r} instead."
            ) from err
        idx = np.asarray(ids) - 1
        if idx.size == 0 or idx.min() < 0 or idx.max() >= n_channels:
            raise PerceptionError(
                f"The 'channels' parameter must name ids in 1..{n_channels}. Got {selection!r} "
                "instead."
            )
        return idx
    raise PerceptionError(
        "The 'channels' parameter must be all, left, right, taxel:N or ids:a,b. Got "
        f"{selection!r} instead."
    )


def refractory_mask(t_ns: np.ndarray, taxel: np.ndarray, rate_hz: float) -> np.ndarray:
    """Events kept when each taxel drops any spike closer than ``1/rate_hz`` to its last kept one.

    This is the paper's NUSkin sampling-rate reduction.

    Args:
        t_ns: Event times, int64 ns, sorted.
        taxel: Taxel ids, same length.
        rate_hz: Target rate per taxel, Hz (> 0).

    Returns:
        Boolean mask of kept events.

    Raises:
        PerceptionError: when the rate is not positive.
    """
    if not rate_hz > 0:
        raise PerceptionError(f"The 'rate_hz' parameter must be > 0. Got {rate_hz!r} instead.")
    t = np.asarray(t_ns, dtype=np.int64)
    tax = np.asarray(taxel)
    tau = round(1e9 / rate_hz)
    keep = np.zeros(len(t), dtype=bool)
    order = np.argsort(tax, kind="stable")
    bounds = np.flatnonzero(np.diff(tax[order])) + 1
    for group in np.split(order, bounds):
        times = t[group]
        local = np.zeros(len(group), dtype=bool)
        last = None
        # spikes are sparse per taxel, so a short loop per taxel is cheap
        for i, ti in enumerate(times):
            if last is None or ti - last >= tau:
                local[i] = True
                last = ti
        keep[group] = local
    return keep


def decimation_indices(n_samples: int, rate_hz: float, base_rate_hz: float) -> np.ndarray:
    """Samples kept when a series at ``base_rate_hz`` is decimated to ``rate_hz``.

    Equally spaced rounded indices over the whole window, as in the paper's preprocessing.

    Args:
        n_samples: Samples in the window.
        rate_hz: Target rate, Hz (<= base).
        base_rate_hz: Rate of the series, Hz.

    Returns:
        Sorted indices.
    """
    if not 0 < rate_hz <= base_rate_hz:
        raise PerceptionError(
            f"The 'rate_hz' parameter must be in (0, {base_rate_hz}]. Got {rate_hz!r} instead."
        )
    if rate_hz >= base_rate_hz:
        return np.arange(n_samples)
    keep = max(int(rate_hz / base_rate_hz * n_samples) + 1, 1)
    return np.unique(np.round(np.linspace(0, n_samples - 1, keep)).astype(int))


def _rebin_matrix(n_in: int, factor: int) -> np.ndarray:
    n_out = n_in // factor
    m = np.zeros((n_in, n_out))
    rows = np.arange(n_out * factor)
    m[rows, rows // factor] = 1.0
    return m


def _select_matrix(n_in: int, idx: np.ndarray) -> np.ndarray:
    m = np.zeros((n_in, len(idx)))
    m[idx, np.arange(len(idx))] = 1.0
    return m


def _dft_matrices(n: int) -> tuple[np.ndarray, np.ndarray]:
    k = np.arange(n // 2 + 1)
    ang = 2.0 * np.pi * np.outer(np.arange(n), k) / n
    return np.cos(ang), -np.sin(ang)


def est_kernel(
    t_s: np.ndarray, weights: list[tuple[np.ndarray, np.ndarray]], slope: float = 0.1
) -> np.ndarray:
    """Evaluate the EST kernel MLP (1 -> 30 -> 30 -> 1, Leaky ReLU) at lags ``t_s`` seconds.

    Args:
        t_s: Lags in seconds, shape (n,).
        weights: Three ``(W, b)`` layers.
        slope: Leaky ReLU negative slope.

    Returns:
        Kernel values, shape (n,).
    """
    h = np.asarray(t_s, dtype=np.float64)[:, None]
    for i, (w, b) in enumerate(weights):
        h = h @ w + b
        if i < len(weights) - 1:
            h = np.where(h > 0, h, slope * h)
    return h[:, 0]


def fit_est_kernel(
    tau_s: float = 0.005, span_s: float = 0.05, seed: int = 0
) -> list[tuple[np.ndarray, np.ndarray]]:
    """Weights of the EST kernel MLP, fitted to a decaying exponential ``exp(-t / tau)``.

    The paper learns this kernel end to end with the classifier (torch). Without torch the
    kernel is fitted to the exponential that EST's authors start from, which keeps the
    parameterisation (2 hidden layers of 30 Leaky ReLU units) but not the task-specific learning.

    Args:
        tau_s: Decay time constant, s.
        span_s: Lags fitted, 0..span_s seconds.
        seed: Initialisation seed.

    Returns:
        Three ``(W, b)`` layers.
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


class WindowFeatures(BaseEstimator, TransformerMixin):
    """Feature set of flattened windows, as a scikit-learn transformer.

    Input ``X``: ``(n_windows, n_channels * n_samples)`` (windows flattened row-major, as in
    ``ContactWindow.data.ravel()``). Output: ``(n_windows, n_features)`` float64.

    Args:
        kind: Feature set name (baseline, fft, est, activity, autoencoder).
        n_channels: Channels of the input windows.
        n_samples: Samples of the input windows.
        period_ns: Sample period of the input windows, ns.
        pre_ns: Pre-onset signal in the input windows, ns.
        sensor: ``"nuskin"`` or ``"biotac"``.
        bin_ns: NUSkin bin for baseline / fft, ns (multiple of ``period_ns``).
        post_ns: Post-onset signal used, ns (None: all of it); earlier samples only.
        rate_hz: BioTac decimation target, Hz (None: full rate).
        channels: Channel selection (see :func:`select_channels`).
        est_samples: EST: equally spaced output samples per channel.
        est_tau_s: EST: kernel decay time constant the kernel MLP is fitted to, s.
        activity_bin_ns: Activity: bin of the all-taxel activity series, ns.
        activity_late_ns: Activity: also sum each taxel's activity from this time after the
            window's start to its end, ns (None: only over the whole window).
        ae_code: Autoencoder: code size.
        ae_max_iter: Autoencoder: training epochs.
        random_state: Seed (autoencoder, EST kernel).
    """

    def __init__(
        self,
        kind: str = "fft",
        n_channels: int = 80,
        n_samples: int = 1200,
        period_ns: int = 250_000,
        pre_ns: int = 50 * MS,
        sensor: str = "nuskin",
        bin_ns: int = 5 * MS,
        post_ns: int | None = None,
        rate_hz: float | None = None,
        channels: str | None = None,
        est_samples: int = 50,
        est_tau_s: float = 0.005,
        activity_bin_ns: int = 250 * MS,
        activity_late_ns: int | None = None,
        ae_code: int = 32,
        ae_max_iter: int = 200,
        random_state: int = 0,
    ) -> None:
        self.kind = kind
        self.n_channels = n_channels
        self.n_samples = n_samples
        self.period_ns = period_ns
        self.pre_ns = pre_ns
        self.sensor = sensor
        self.bin_ns = bin_ns
        self.post_ns = post_ns
        self.rate_hz = rate_hz
        self.channels = channels
        self.est_samples = est_samples
        self.est_tau_s = est_tau_s
        self.activity_bin_ns = activity_bin_ns
        self.activity_late_ns = activity_late_ns
        self.ae_code = ae_code
        self.ae_max_iter = ae_max_iter
        self.random_state = random_state

    # -- construction of the fixed maps ------------------------------------------------------
    def _used_samples(self) -> int:
        if self.post_ns is None:
            return self.n_samples
        used = int((self.pre_ns + self.post_ns) // self.period_ns)
        if not 0 < used <= self.n_samples:
            raise PerceptionError(
                f"The 'post_ns' parameter must leave 1..{self.n_samples} samples of the window. "
                f"Got {self.post_ns} ({used} samples) instead."
            )
        return used

    def _reduce_matrix(self, used: int) -> np.ndarray:
        """Time map from the window to the series the features see (rebin or decimate)."""
        if self.sensor == "nuskin":
            factor = max(round(self.bin_ns / self.period_ns), 1)
            if factor * self.period_ns != self.bin_ns and factor > 1:
                raise PerceptionError(
                    "The 'bin_ns' parameter must be a multiple of the window period "
                    f"{self.period_ns}. "
                    f"Got {self.bin_ns} instead."
                )
            if used // factor < 1:
                raise PerceptionError(
                    f"The 'bin_ns' parameter must fit the window. Got {self.bin_ns} instead."
                )
            return _rebin_matrix(used, factor)
        base = 1e9 / self.period_ns
        if self.rate_hz is None:
            return np.eye(used)
        return _select_matrix(used, decimation_indices(used, float(self.rate_hz), base))

    def _check_params(self) -> None:
        kind = FeatureKind.parse(self.kind)
        if self.sensor not in ("nuskin", "biotac"):
            raise PerceptionError(
                f"The 'sensor' parameter must be 'nuskin' or 'biotac'. Got {self.sensor!r} instead."
            )
        for name in (
            "n_channels",
            "n_samples",
            "period_ns",
            "bin_ns",
            "est_samples",
            "ae_code",
            "activity_bin_ns",
        ):
            value = getattr(self, name)
            if not (isinstance(value, (int, np.integer)) and value > 0):
                raise PerceptionError(
                    f"The {name!r} parameter must be a positive integer. Got {value!r} instead."
                )
        if kind is FeatureKind.ACTIVITY and self.sensor != "nuskin":
            raise PerceptionError(
                "The 'kind' parameter 'activity' needs NUSkin windows. Got biotac instead."
            )

    def fit(self, X: np.ndarray, y: np.ndarray | None = None) -> WindowFeatures:
        """Build the maps for the geometry (and train the autoencoder on ``X``).

        Args:
            X: Flattened windows ``(n_windows, n_channels * n_samples)``.
            y: Ignored.

        Returns:
            self
        """
        self._check_params()
        kind = FeatureKind.parse(self.kind)
        self.kind_ = kind
        self.channel_index_ = select_channels(self.channels, self.n_channels)
        used = self._used_samples()
        self.used_samples_ = used
        self.ae_layers_: list[tuple[np.ndarray, np.ndarray]] = []
        self.ae_mean_ = self.ae_scale_ = None
        if kind is FeatureKind.BASELINE:
            self.time_maps_ = [self._pad(self._reduce_matrix(used))]
        elif kind in (FeatureKind.FFT, FeatureKind.AUTOENCODER):
            r = self._reduce_matrix(used)
            cos, sin = _dft_matrices(r.shape[1])
            self.time_maps_ = [self._pad(r @ cos), self._pad(r @ sin)]
        elif kind is FeatureKind.EST:
            self.time_maps_ = [self._pad(self._est_matrix(used))]
        else:  # ACTIVITY
            factor = max(int(self.activity_bin_ns // self.period_ns), 1)
            rb = _rebin_matrix(used, factor)
            cols = [rb, np.ones((used, 1))]
            if self.activity_late_ns is not None:
                late = np.zeros((used, 1))
                late[min(int(self.activity_late_ns // self.period_ns), used - 1) :] = 1.0
                cols.append(late)
            self.activity_bins_ = rb.shape[1]
            self.time_maps_ = [self._pad(np.concatenate(cols, axis=1))]
        self.time_maps32_ = [m.astype(np.float32) for m in self.time_maps_]
        if kind is FeatureKind.AUTOENCODER:
            self._fit_autoencoder(self._base(self._validate(X)))
        self.n_features_out_ = int(
            self.transform(np.zeros((1, self.n_channels * self.n_samples), np.float32)).shape[1]
        )
        return self

    def _pad(self, m: np.ndarray) -> np.ndarray:
        """Rows for the samples beyond ``post_ns`` are zero, so the map takes the whole window."""
        if m.shape[0] == self.n_samples:
            return m
        out = np.zeros((self.n_samples, m.shape[1]))
        out[: m.shape[0]] = m
        return out

    def _est_matrix(self, used: int) -> np.ndarray:
        weights = fit_est_kernel(
            self.est_tau_s, span_s=max(10 * self.est_tau_s, 0.01), seed=self.random_state
        )
        self.est_weights_ = weights
        times = np.linspace(0, used - 1, self.est_samples).round().astype(int)
        lags = (times[None, :] - np.arange(used)[:, None]) * (self.period_ns * 1e-9)
        m = np.zeros((used, self.est_samples))
        causal = lags >= 0
        m[causal] = est_kernel(lags[causal], weights)
        span = max(10 * self.est_tau_s, 0.01)
        m[lags > span] = 0.0
        return m

    def _fit_autoencoder(self, base: np.ndarray) -> None:
        from sklearn.neural_network import MLPRegressor

        self.ae_mean_ = base.mean(axis=0)
        scale = base.std(axis=0)
        self.ae_scale_ = np.where(scale > 1e-12, scale, 1.0)
        z = (base - self.ae_mean_) / self.ae_scale_
        net = MLPRegressor(
            hidden_layer_sizes=(128, 64, self.ae_code, 64, 128),
            activation="relu",
            max_iter=self.ae_max_iter,
            random_state=self.random_state,
            early_stopping=False,
        )
        import warnings

        from sklearn.exceptions import ConvergenceWarning

        with warnings.catch_warnings():
            warnings.simplefilter("ignore", ConvergenceWarning)
            net.fit(z, z)
        self.ae_layers_ = [
            (w.copy(), b.copy()) for w, b in zip(net.coefs_[:3], net.intercepts_[:3], strict=True)
        ]

    # -- evaluation --------------------------------------------------------------------------
    def _validate(self, X: np.ndarray) -> np.ndarray:
        x = np.asarray(X)
        if x.ndim == 3:
            x = x.reshape(x.shape[0], -1)
        if x.ndim != 2 or x.shape[1] != self.n_channels * self.n_samples:
            raise PerceptionError(
                f"The 'X' parameter must have shape (n, {self.n_channels * self.n_samples}) "
                f"(= {self.n_channels} channels x {self.n_samples} samples). Got {np.shape(X)} "
                "instead."
            )
        if not np.isfinite(x).all():
            raise PerceptionError(
                "The 'X' parameter (window data) must be finite. Got NaN or inf instead."
            )
        return x

    def _base(self, x: np.ndarray) -> np.ndarray:
        x3 = x.reshape(x.shape[0], self.n_channels, self.n_samples)[:, self.channel_index_, :]
        x3 = x3.astype(np.float64, copy=False)
        kind = self.kind_
        if kind is FeatureKind.BASELINE or kind is FeatureKind.EST:
            return (x3 @ self.time_maps_[0]).reshape(x.shape[0], -1)
        if kind in (FeatureKind.FFT, FeatureKind.AUTOENCODER):
            re = x3 @ self.time_maps_[0]
            im = x3 @ self.time_maps_[1]
            mag = np.sqrt(re * re + im * im) * (FFT_SCALE_IN * FFT_SCALE_OUT)
            return mag.reshape(x.shape[0], -1)
        a = np.abs(x3) @ self.time_maps_[0]  # (n, C, n_bins + segments)
        nb = self.activity_bins_
        over_time = np.log1p(a[:, :, :nb].sum(axis=1))
        per_taxel = np.log1p(a[:, :, nb:]).reshape(x.shape[0], -1)
        return np.concatenate([over_time, per_taxel], axis=1)

    def transform(self, X: np.ndarray) -> np.ndarray:
        """Features of flattened windows.

        Args:
            X: ``(n_windows, n_channels * n_samples)`` (or ``(n, n_channels, n_samples)``).

        Returns:
            ``(n_windows, n_features)`` float64.

        Raises:
            PerceptionError: on a wrong shape or NaN/inf in the windows.
        """
        if not hasattr(self, "time_maps_"):
            raise PerceptionError("This WindowFeatures is not fitted yet: call fit() first.")
        x = self._validate(X)
        out = self._base(x)
        if self.kind_ is FeatureKind.AUTOENCODER:
            h = (out - self.ae_mean_) / self.ae_scale_
            for w, b in self.ae_layers_:
                h = np.maximum(h @ w + b, 0.0)
            out = h
        return out

    def geometry(self) -> Geometry:
        """The window geometry this transformer accepts."""
        return Geometry(self.n_channels, self.n_samples, self.period_ns, self.pre_ns, self.sensor)


def window_matrix(windows: list, geometry: Geometry) -> np.ndarray:
    """Stack window data into ``(n, n_channels * n_samples)`` float32, cropping longer windows.

    Args:
        windows: ``ContactWindow``s (or arrays ``(n_channels, n_samples)``).
        geometry: The geometry to fit.

    Returns:
        The flattened windows.

    Raises:
        PerceptionError: when a window is shorter, has other channels or another period.
    """
    rows = [as_model_input(w, geometry) for w in windows]
    if not rows:
        return np.zeros((0, geometry.n_channels * geometry.n_samples), np.float32)
    return np.stack(rows)


def as_model_input(window: object, geometry: Geometry) -> np.ndarray:
    """One window as a flat float32 row for a model of ``geometry``.

    A window whose pre-onset part or total length is longer than the model's is cropped to it
    (same onset). A NUSkin window at a finer bin whose period divides the model's is rebinned by
    summing (counts add exactly), so 0.25 ms online windows feed models trained on 1 ms bins.

    Args:
        window: A ``ContactWindow`` or an array ``(n_channels, n_samples)``.
        geometry: The model's geometry.

    Returns:
        Flat ``(n_channels * n_samples,)`` float32.

    Raises:
        PerceptionError: on a window too short, with other channels or an incompatible
            sample period, or holding NaN/inf.
    """
    data = getattr(window, "data", window)
    x = np.asarray(data)
    if x.ndim == 1 and hasattr(window, "channels"):
        x = x.reshape(len(window.channels), -1)  # type: ignore[attr-defined]
    if x.ndim != 2 or x.shape[0] != geometry.n_channels:
        raise PerceptionError(
            f"The 'window.data' parameter must have {geometry.n_channels} channels. Got shape "
            f"{x.shape} instead."
        )
    factor = 1
    if hasattr(window, "sample_period_ns"):
        period = int(window.sample_period_ns)  # type: ignore[attr-defined]
        if period != geometry.period_ns:
            if geometry.sensor != "nuskin" or period <= 0 or geometry.period_ns % period:
                raise PerceptionError(
                    f"The 'window.sample_period_ns' parameter must be {geometry.period_ns} "
                    f"(or divide it, NUSkin). Got {period} instead."
                )
            factor = geometry.period_ns // period
        extra_pre = int(window.pre_onset_ns) - geometry.pre_ns  # type: ignore[attr-defined]
        if extra_pre < 0 or extra_pre % period:
            raise PerceptionError(
                f"The 'window.pre_onset_ns' parameter must be >= {geometry.pre_ns}. "
                f"Got {int(window.pre_onset_ns)} instead."  # type: ignore[attr-defined]
            )
        x = x[:, extra_pre // period :]
    need = geometry.n_samples * factor
    if x.shape[1] < need:
        raise PerceptionError(
            f"The 'window.data' parameter must hold at least {need} samples after the model's "
            f"pre-onset start. Got {x.shape[1]} instead."
        )
    x = x[:, :need]
    if not np.isfinite(x).all():
        raise PerceptionError("The 'window.data' parameter must be finite. Got NaN or inf instead.")
    if factor > 1:
        x = x.reshape(x.shape[0], geometry.n_samples, factor).sum(axis=2)
    return np.ascontiguousarray(x, dtype=np.float32).ravel()
