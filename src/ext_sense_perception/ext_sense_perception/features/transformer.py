# ruff: noqa: N803  (X / F for sample matrices, as in scikit-learn)
"""Feature families of contact windows, one scikit-learn transformer each (no ROS).

Every family is a fixed linear map along the window's time axis followed by at most a few
element-wise steps, so the NumPy path is vectorised and
:mod:`ext_sense_perception.training.onnx_export` writes the same pipeline in ONNX. Input ``X``
is ``(n_windows, n_channels * n_samples)`` (``ContactWindow.data.ravel()`` per row), so a
family can head a ``Pipeline`` tuned inside CV folds; output float64. BioTac decimation is part
of the map (``rate_hz``); the NUSkin refractory drop works on events, before binning.
"""

from __future__ import annotations

import warnings
from typing import Any, ClassVar

import numpy as np
from scipy.signal.windows import tukey
from sklearn.base import BaseEstimator, TransformerMixin
from sklearn.exceptions import ConvergenceWarning
from sklearn.neural_network import MLPRegressor
from sklearn.utils.validation import check_is_fitted

from ext_sense_perception.errors import PerceptionError
from ext_sense_perception.features.est_kernel import est_kernel, fit_est_kernel
from ext_sense_perception.features.inputs import dense_array
from ext_sense_perception.features.maps import (
    BIN_KERNELS,
    FFT_SCALE_IN,
    FFT_SCALE_OUT,
    FeatureKind,
    decimation_indices,
    dft_matrices,
    rebin_matrix,
    select_channels,
    select_matrix,
)
from ext_sense_perception.online.model_input import Geometry
from ext_sense_runtime.stamps import MS


def _positive_int(owner: object, *names: str) -> None:
    for name in names:
        value = getattr(owner, name)
        if not (isinstance(value, (int, np.integer)) and value > 0):
            raise PerceptionError(
                f"The {name!r} parameter must be a positive integer. Got {value!r} instead."
            )


class WindowFeatures(TransformerMixin, BaseEstimator):
    """What every feature family shares: geometry, channels, crop, checks, the fitted state.

    Subclasses set :attr:`kind`, add their parameters and implement :meth:`_time_maps` (and
    :meth:`_features` when they are not one time map). ``post_ns`` crops the window after the onset
    (None: all of it); ``channels`` is a selection (:func:`~.maps.select_channels`).
    """

    kind: ClassVar[str] = ""

    def __init__(
        self,
        n_channels: int = 80,
        n_samples: int = 300,
        period_ns: int = 1 * MS,
        pre_ns: int = 50 * MS,
        sensor: str = "nuskin",
        post_ns: int | None = None,
        channels: str | None = None,
    ) -> None:
        self.n_channels = n_channels
        self.n_samples = n_samples
        self.period_ns = period_ns
        self.pre_ns = pre_ns
        self.sensor = sensor
        self.post_ns = post_ns
        self.channels = channels

    # -- fitting -----------------------------------------------------------------------------
    def _check_params(self) -> None:
        if self.sensor not in ("nuskin", "biotac"):
            raise PerceptionError(
                f"The 'sensor' parameter must be 'nuskin' or 'biotac'. Got {self.sensor!r} instead."
            )
        _positive_int(self, "n_channels", "n_samples", "period_ns")

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

    def _time_maps(self, used: int) -> list[np.ndarray]:
        raise NotImplementedError

    def _fit_features(self, x: np.ndarray) -> None:
        """Learned state beyond the fixed maps (the autoencoder); ``x`` are checked windows."""

    def fit(self, X: np.ndarray, y: np.ndarray | None = None) -> WindowFeatures:
        """Build the maps for the geometry (and learn what the family learns from ``X``).

        PerceptionError: a parameter out of range, or windows of another shape or not finite.
        """
        self._check_params()
        self.kind_ = FeatureKind.parse(self.kind)
        self.channel_index_ = select_channels(self.channels, self.n_channels)
        self.used_samples_ = self._used_samples()
        self.time_maps_ = [self._pad(m) for m in self._time_maps(self.used_samples_)]
        self.n_features_in_ = self.n_channels * self.n_samples
        self._fit_features(self._validate(X))
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

    # -- evaluation --------------------------------------------------------------------------
    def _validate(self, X: np.ndarray) -> np.ndarray:
        x = dense_array(X, allow_nd=True, ensure_all_finite=False)  # dense numbers, not empty
        if not np.isfinite(x).all():
            raise PerceptionError(
                "The 'X' parameter (window data) must be finite. Got NaN or inf instead."
            )
        if x.ndim == 3:
            x = x.reshape(x.shape[0], -1)
        if x.ndim != 2 or x.shape[1] != self.n_channels * self.n_samples:
            raise PerceptionError(
                f"The 'X' parameter must have shape (n, {self.n_channels * self.n_samples}) "
                f"(= {self.n_channels} channels x {self.n_samples} samples). Got {x.shape} "
                "instead."
            )
        return x

    def _selected(self, x: np.ndarray) -> np.ndarray:
        x3 = x.reshape(x.shape[0], self.n_channels, self.n_samples)[:, self.channel_index_, :]
        return x3.astype(np.float64, copy=False)

    def _features(self, x3: np.ndarray) -> np.ndarray:
        """Features of the selected channels ``(n, C, n_samples)``: one time map, flattened."""
        return (x3 @ self.time_maps_[0]).reshape(x3.shape[0], -1)

    def transform(self, X: np.ndarray) -> np.ndarray:
        """Features ``(n_windows, n_features)`` float64 of flattened (or 3-D) windows.

        NotFittedError before :meth:`fit`; PerceptionError on a wrong shape or NaN/inf.
        """
        check_is_fitted(self, "time_maps_")
        return self._features(self._selected(self._validate(X)))

    def geometry(self) -> Geometry:
        """The window geometry this transformer accepts."""
        return Geometry(self.n_channels, self.n_samples, self.period_ns, self.pre_ns, self.sensor)


class _Reduced(WindowFeatures):
    """A family that first reduces the window's time axis: NUSkin rebinning, BioTac decimation.

    ``bin_ns`` is the NUSkin feature bin (a multiple of ``period_ns``), ``bin_kernel`` its weights
    (``box``, the paper's sums, or ``gauss``, :func:`~.maps.gauss_rebin_matrix`); ``rate_hz`` the
    BioTac decimation target (None: full rate).
    """

    def __init__(
        self,
        n_channels: int = 80,
        n_samples: int = 300,
        period_ns: int = 1 * MS,
        pre_ns: int = 50 * MS,
        sensor: str = "nuskin",
        post_ns: int | None = None,
        channels: str | None = None,
        bin_ns: int = 5 * MS,
        rate_hz: float | None = None,
        bin_kernel: str = "box",
    ) -> None:
        super().__init__(n_channels, n_samples, period_ns, pre_ns, sensor, post_ns, channels)
        self.bin_ns = bin_ns
        self.rate_hz = rate_hz
        self.bin_kernel = bin_kernel

    def _check_params(self) -> None:
        super()._check_params()
        _positive_int(self, "bin_ns")
        if self.bin_kernel not in BIN_KERNELS:
            raise PerceptionError(
                f"The 'bin_kernel' parameter must be one of {', '.join(BIN_KERNELS)}. Got "
                f"{self.bin_kernel!r} instead."
            )

    def _reduce_matrix(self, used: int) -> np.ndarray:
        """Time map from the window to the series the features see (rebin or decimate)."""
        if self.sensor == "nuskin":
            factor = max(round(self.bin_ns / self.period_ns), 1)
            if factor * self.period_ns != self.bin_ns and factor > 1:
                raise PerceptionError(
                    "The 'bin_ns' parameter must be a multiple of the window period "
                    f"{self.period_ns}. Got {self.bin_ns} instead."
                )
            if used // factor < 1:
                raise PerceptionError(
                    f"The 'bin_ns' parameter must fit the window. Got {self.bin_ns} instead."
                )
            return rebin_matrix(used, factor, self.bin_kernel)
        base = 1e9 / self.period_ns
        if self.rate_hz is None:
            return np.eye(used)
        return select_matrix(used, decimation_indices(used, float(self.rate_hz), base))


class BaselineFeatures(_Reduced):
    """The paper's baseline: NUSkin signed counts in ``bin_ns`` bins; BioTac raw (decimated) PAC."""

    kind = "baseline"

    def _time_maps(self, used: int) -> list[np.ndarray]:
        return [self._reduce_matrix(used)]


class FFTFeatures(_Reduced):
    """|FFT| of each channel's binned (NUSkin) or decimated (BioTac) series, the paper's scaling.

    ``taper`` is the share of the series a Tukey window tapers before the transform (0: none,
    the paper's; 1: a Hann window). A rod still rings when the window ends, so without it the
    cut at each end leaks into every frequency, and moving the onset by a millisecond or two
    moves that leakage (docs/perception.md, "The default tap model's figures").
    """

    kind = "fft"

    def __init__(
        self,
        n_channels: int = 80,
        n_samples: int = 300,
        period_ns: int = 1 * MS,
        pre_ns: int = 50 * MS,
        sensor: str = "nuskin",
        post_ns: int | None = None,
        channels: str | None = None,
        bin_ns: int = 5 * MS,
        rate_hz: float | None = None,
        bin_kernel: str = "box",
        taper: float = 0.0,
    ) -> None:
        super().__init__(
            n_channels, n_samples, period_ns, pre_ns, sensor, post_ns, channels, bin_ns, rate_hz,
            bin_kernel,
        )  # fmt: skip
        self.taper = taper

    def _check_params(self) -> None:
        super()._check_params()
        if not (isinstance(self.taper, (int, float)) and 0.0 <= self.taper <= 1.0):
            raise PerceptionError(
                f"The 'taper' parameter must be a share in [0, 1]. Got {self.taper!r} instead."
            )

    def _time_maps(self, used: int) -> list[np.ndarray]:
        r = self._reduce_matrix(used)
        if self.taper > 0:
            r = r * tukey(r.shape[1], float(self.taper))[None, :]
        cos, sin = dft_matrices(r.shape[1])
        return [r @ cos, r @ sin]

    def _features(self, x3: np.ndarray) -> np.ndarray:
        re = x3 @ self.time_maps_[0]
        im = x3 @ self.time_maps_[1]
        mag = np.sqrt(re * re + im * im) * (FFT_SCALE_IN * FFT_SCALE_OUT)
        return mag.reshape(x3.shape[0], -1)


class AutoencoderFeatures(FFTFeatures):
    """The ``ae_code``-d code of an MLP autoencoder trained on the windows' FFT features."""

    kind = "autoencoder"

    def __init__(
        self,
        n_channels: int = 80,
        n_samples: int = 300,
        period_ns: int = 1 * MS,
        pre_ns: int = 50 * MS,
        sensor: str = "nuskin",
        post_ns: int | None = None,
        channels: str | None = None,
        bin_ns: int = 5 * MS,
        rate_hz: float | None = None,
        ae_code: int = 32,
        ae_max_iter: int = 200,
        random_state: int = 0,
        bin_kernel: str = "box",
        taper: float = 0.0,
    ) -> None:
        super().__init__(
            n_channels,
            n_samples,
            period_ns,
            pre_ns,
            sensor,
            post_ns,
            channels,
            bin_ns,
            rate_hz,
            bin_kernel,
            taper,
        )
        self.ae_code = ae_code
        self.ae_max_iter = ae_max_iter
        self.random_state = random_state

    def _check_params(self) -> None:
        super()._check_params()
        _positive_int(self, "ae_code", "ae_max_iter")

    def _fit_features(self, x: np.ndarray) -> None:
        base = super()._features(self._selected(x))
        self.ae_mean_ = base.mean(axis=0)
        scale = base.std(axis=0)
        self.ae_scale_ = np.where(scale > 1e-12, scale, 1.0)
        # trained in float32: twice as fast (it was most of the full report's fit time) and
        # the same reconstruction loss; the code is then computed in float64 as every feature
        z = ((base - self.ae_mean_) / self.ae_scale_).astype(np.float32)
        net = MLPRegressor(
            hidden_layer_sizes=(128, 64, self.ae_code, 64, 128),
            activation="relu",
            max_iter=self.ae_max_iter,
            random_state=self.random_state,
            early_stopping=False,
        )
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", ConvergenceWarning)
            net.fit(z, z)
        self.ae_layers_ = [
            (w.astype(np.float64), b.astype(np.float64))
            for w, b in zip(net.coefs_[:3], net.intercepts_[:3], strict=True)
        ]

    def _features(self, x3: np.ndarray) -> np.ndarray:
        h = (super()._features(x3) - self.ae_mean_) / self.ae_scale_
        for w, b in self.ae_layers_:
            h = np.maximum(h @ w + b, 0.0)
        return h


class ESTFeatures(WindowFeatures):
    """Event Spike Tensor style: each channel convolved with a learned-shape decaying kernel.

    The kernel MLP is fitted to ``exp(-t / est_tau_s)`` (:mod:`.est_kernel`); ``est_samples``
    equally spaced outputs per channel.
    """

    kind = "est"

    def __init__(
        self,
        n_channels: int = 80,
        n_samples: int = 300,
        period_ns: int = 1 * MS,
        pre_ns: int = 50 * MS,
        sensor: str = "nuskin",
        post_ns: int | None = None,
        channels: str | None = None,
        est_samples: int = 50,
        est_tau_s: float = 0.005,
        random_state: int = 0,
    ) -> None:
        super().__init__(n_channels, n_samples, period_ns, pre_ns, sensor, post_ns, channels)
        self.est_samples = est_samples
        self.est_tau_s = est_tau_s
        self.random_state = random_state

    def _check_params(self) -> None:
        super()._check_params()
        _positive_int(self, "est_samples")

    def _time_maps(self, used: int) -> list[np.ndarray]:
        span = max(10 * self.est_tau_s, 0.01)
        weights = fit_est_kernel(self.est_tau_s, span_s=span, seed=self.random_state)
        times = np.linspace(0, used - 1, self.est_samples).round().astype(int)
        lags = (times[None, :] - np.arange(used)[:, None]) * (self.period_ns * 1e-9)
        m = np.zeros((used, self.est_samples))
        causal = lags >= 0
        m[causal] = est_kernel(lags[causal], weights)
        m[lags > span] = 0.0
        return [m]


class ActivityFeatures(WindowFeatures):
    """NUSkin only: log1p event activity over time (all taxels) and per taxel over the window.

    ``activity_bin_ns`` bins the all-taxel series; ``activity_late_ns`` (None: not) also sums each
    taxel's activity from that time after the window's start.
    """

    kind = "activity"

    def __init__(
        self,
        n_channels: int = 80,
        n_samples: int = 300,
        period_ns: int = 1 * MS,
        pre_ns: int = 50 * MS,
        sensor: str = "nuskin",
        post_ns: int | None = None,
        channels: str | None = None,
        activity_bin_ns: int = 250 * MS,
        activity_late_ns: int | None = None,
    ) -> None:
        super().__init__(n_channels, n_samples, period_ns, pre_ns, sensor, post_ns, channels)
        self.activity_bin_ns = activity_bin_ns
        self.activity_late_ns = activity_late_ns

    def _check_params(self) -> None:
        super()._check_params()
        _positive_int(self, "activity_bin_ns")
        if self.sensor != "nuskin":
            raise PerceptionError(
                "The 'activity' features need NUSkin windows. Got sensor 'biotac' instead."
            )

    def _time_maps(self, used: int) -> list[np.ndarray]:
        factor = max(int(self.activity_bin_ns // self.period_ns), 1)
        rb = rebin_matrix(used, factor)
        cols = [rb, np.ones((used, 1))]
        if self.activity_late_ns is not None:
            late = np.zeros((used, 1))
            late[min(int(self.activity_late_ns // self.period_ns), used - 1) :] = 1.0
            cols.append(late)
        self.activity_bins_ = rb.shape[1]
        return [np.concatenate(cols, axis=1)]

    def _features(self, x3: np.ndarray) -> np.ndarray:
        a = np.abs(x3) @ self.time_maps_[0]  # (n, C, n_bins + segments)
        nb = self.activity_bins_
        over_time = np.log1p(a[:, :, :nb].sum(axis=1))
        per_taxel = np.log1p(a[:, :, nb:]).reshape(x3.shape[0], -1)
        return np.concatenate([over_time, per_taxel], axis=1)


FAMILIES: dict[FeatureKind, type[WindowFeatures]] = {
    FeatureKind.BASELINE: BaselineFeatures,
    FeatureKind.FFT: FFTFeatures,
    FeatureKind.EST: ESTFeatures,
    FeatureKind.ACTIVITY: ActivityFeatures,
    FeatureKind.AUTOENCODER: AutoencoderFeatures,
}


def make_features(kind: str | FeatureKind, **params: Any) -> WindowFeatures:
    """The feature family named ``kind`` (aliases such as ``raw`` allowed) with ``params``.

    PerceptionError: an unknown family, or a parameter the family does not have.
    """
    family = FAMILIES[FeatureKind.parse(kind)]
    unknown = set(params) - set(family._get_param_names())
    if unknown:
        raise PerceptionError(
            f"The {family.kind!r} features have no parameter {sorted(unknown)}; they take "
            f"{family._get_param_names()}."
        )
    return family(**params)
