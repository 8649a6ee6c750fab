# ruff: noqa: N803  (X for sample matrices, as in scikit-learn)
"""A taxel-wise stacked SVR for tap localisation (no ROS).

One RBF SVR over all 80 taxels is diluted by the taxels that see little of a tap.
:class:`TaxelStackSVR` fits one RBF SVR per channel block of the features and a ridge that
combines them, trained on out-of-fold predictions so it weighs channels by how well they
generalise. Scaling is the pipeline's ``StandardScaler`` (per feature, so per block).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from sklearn.base import BaseEstimator, RegressorMixin
from sklearn.linear_model import RidgeCV
from sklearn.model_selection import KFold
from sklearn.svm import SVR
from sklearn.utils.validation import check_is_fitted

from ext_sense_perception.errors import PerceptionError
from ext_sense_perception.features.inputs import validated

# ridge penalties on metre labels: the squared error of metre predictions is 1e-4 of the cm one
# while the penalty on the (unitless) weights is not, so these are 1e-3 .. 1e5 on cm labels
# (on 900 simulated 30 cm rod taps the search picked 0.1 m^2 = 1e3 cm^2, inside this range)
RIDGE_ALPHAS_M2 = tuple(float(a) for a in np.logspace(-7.0, 1.0, 17))
_CHUNK = 64  # windows per native kernel block: 80 channels x 64 x ~1000 SVs x 8 B = 41 MB


class TaxelStackSVR(RegressorMixin, BaseEstimator):
    """Per-channel RBF SVRs combined by ridge regression trained on out-of-fold predictions.

    ``X`` is ``(n_windows, n_channels * n_per_channel)``, channel-major. ``C`` and ``epsilon`` are
    in label units (1.0 on metres = the paper's 100 on cm); ``gamma="scale"`` is per block. The
    ridge is trained on ``inner_folds`` out-of-fold predictions, its penalty chosen among ``alphas``
    by generalised cross-validation.
    """

    def __init__(
        self,
        n_channels: int = 80,
        C: float = 1.0,
        gamma: str | float = "scale",
        epsilon: float = 0.001,
        inner_folds: int = 3,
        alphas: tuple[float, ...] = RIDGE_ALPHAS_M2,
        random_state: int = 0,
    ) -> None:
        self.n_channels = n_channels
        self.C = C
        self.gamma = gamma
        self.epsilon = epsilon
        self.inner_folds = inner_folds
        self.alphas = alphas
        self.random_state = random_state

    def _svr(self) -> SVR:
        return SVR(kernel="rbf", C=self.C, gamma=self.gamma, epsilon=self.epsilon)

    def _blocks(self, x: np.ndarray) -> np.ndarray:
        """Checked ``x`` as ``(n_windows, n_channels, n_per_channel)``."""
        c = self.n_channels
        if not (isinstance(c, (int, np.integer)) and c > 0) or x.shape[1] % c:
            raise PerceptionError(
                f"The 'n_channels' parameter must be a positive integer dividing the "
                f"{x.shape[1]} features into equal blocks. Got {c!r} instead."
            )
        return x.reshape(x.shape[0], c, x.shape[1] // c)

    def fit(self, X: np.ndarray, y: np.ndarray) -> TaxelStackSVR:
        """Fit the combiner on out-of-fold channel predictions, then every channel on all of X.

        PerceptionError: bad shapes, NaN/inf, or fewer windows than inner folds.
        """
        x, target = validated(
            self, X, y, reset=True, dtype=np.float64, y_numeric=True, ensure_min_samples=2
        )
        blocks = self._blocks(x)
        n = blocks.shape[0]
        folds = self.inner_folds
        if not (isinstance(folds, (int, np.integer)) and 2 <= folds <= n):
            raise PerceptionError(
                f"The 'inner_folds' parameter must be an integer in [2, {n}] (windows). "
                f"Got {folds!r} instead."
            )
        oof = np.zeros((n, self.n_channels))
        cv = KFold(int(folds), shuffle=True, random_state=self.random_state)
        for train, held in cv.split(blocks):
            for c in range(self.n_channels):
                part = self._svr().fit(blocks[train, c], target[train])
                oof[held, c] = part.predict(blocks[held, c])
        self.combiner_ = RidgeCV(alphas=np.asarray(self.alphas, dtype=np.float64)).fit(oof, target)
        self.svrs_ = [self._svr().fit(blocks[:, c], target) for c in range(self.n_channels)]
        self.coef_ = np.asarray(self.combiner_.coef_, dtype=np.float64).reshape(-1)
        self.intercept_ = float(self.combiner_.intercept_)
        self.alpha_ = float(self.combiner_.alpha_)
        self.packed_ = self._pack()
        return self

    def _pack(self) -> dict[str, np.ndarray]:
        """Every channel's SVR as padded arrays (zero coefficients pad the support vectors)."""
        d = self.n_features_in_ // self.n_channels
        n_sv = max(max(len(s.support_vectors_) for s in self.svrs_), 1)
        centre = np.zeros((self.n_channels, d))
        sv = np.zeros((self.n_channels, n_sv, d))
        dual = np.zeros((self.n_channels, n_sv))
        for c, s in enumerate(self.svrs_):
            vectors = np.asarray(s.support_vectors_, dtype=np.float64)
            if len(vectors):
                centre[c] = vectors.mean(axis=0)
                sv[c, : len(vectors)] = vectors - centre[c]
                dual[c, : len(vectors)] = np.asarray(s.dual_coef_).reshape(-1)
        return {
            "centre": centre,
            "sv": sv,
            "dual": dual,
            "gamma": np.array([float(s._gamma) for s in self.svrs_]),
            "b": np.array([float(np.asarray(s.intercept_).reshape(-1)[0]) for s in self.svrs_]),
        }

    def channel_predictions(self, X: np.ndarray) -> np.ndarray:
        """Every channel's SVR prediction, ``(n_windows, n_channels)``.

        All channels at once on the packed support vectors (one ``SVR.predict`` per channel took 21
        ms a window), the same kernel sums on inputs centred per block. NotFittedError before
        :meth:`fit`; PerceptionError on bad shapes or NaN/inf.
        """
        check_is_fitted(self, "packed_")
        p = self.packed_
        blocks = self._blocks(validated(self, X, reset=False, dtype=np.float64))
        sv_t = p["sv"].transpose(0, 2, 1)
        ss = np.einsum("csd,csd->cs", p["sv"], p["sv"])[:, None, :]
        out = np.empty((blocks.shape[0], self.n_channels))
        for start in range(0, blocks.shape[0], _CHUNK):  # kernel rows: channels x chunk x n_sv
            xc = blocks[start : start + _CHUNK].transpose(1, 0, 2) - p["centre"][:, None, :]
            d2 = np.einsum("cnd,cnd->cn", xc, xc)[:, :, None] - 2.0 * (xc @ sv_t) + ss
            k = np.exp(-p["gamma"][:, None, None] * np.maximum(d2, 0.0))
            out[start : start + _CHUNK] = (
                np.einsum("cns,cs->cn", k, p["dual"]) + p["b"][:, None]
            ).T
        return out

    def predict(self, X: np.ndarray) -> np.ndarray:
        """Combined predictions, ``(n_windows,)`` (errors as :meth:`channel_predictions`)."""
        return self.channel_predictions(X) @ self.coef_ + self.intercept_

    def onnx_arrays(self) -> dict[str, Any]:
        """The fitted model as padded float64 arrays for one batched ONNX ``MatMul``.

        ``centre`` ``(n_channels, d)``, centred ``sv`` ``(n_channels, n_sv, d)``, ``coef``
        ``(n_channels, n_sv)`` (the ridge weights folded in), ``gamma`` ``(n_channels,)`` and the
        scalar ``intercept``.
        """
        check_is_fitted(self, "packed_")
        p = self.packed_
        return {
            "centre": p["centre"],
            "sv": p["sv"],
            "coef": p["dual"] * self.coef_[:, None],
            "gamma": p["gamma"],
            "intercept": float(self.intercept_ + self.coef_ @ p["b"]),
        }
