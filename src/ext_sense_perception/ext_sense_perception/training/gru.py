# ruff: noqa: N803, N806  (X / F for sample matrices, as in scikit-learn)
"""GRU(16) + MLP(16, 8) estimator on the binned series (the paper's RNN; torch, optional extra).

The network is kept as NumPy arrays (:class:`GRUNet`) and as torch's ONNX export (``onnx_``,
spliced in by :mod:`.onnx_export`), so a fitted estimator pickles and exports without torch;
only :meth:`GRUEstimator.predict` needs it.
"""

from __future__ import annotations

import importlib.util
import io
import warnings
import weakref
from typing import Any, NamedTuple

import numpy as np
from sklearn.base import BaseEstimator, ClassifierMixin, RegressorMixin
from sklearn.utils import ClassifierTags, RegressorTags
from sklearn.utils.metaestimators import available_if
from sklearn.utils.multiclass import check_classification_targets
from sklearn.utils.validation import check_is_fitted

from ext_sense_perception.errors import PerceptionError
from ext_sense_perception.features.inputs import validated

AUTO_UNSCALED_RMS = (0.1, 30.0)  # inputs of this RMS train better unscaled (see input_scaling)
# torch modules rebuilt from an estimator's NumPy weights, kept beside it (never pickled, and
# predict leaves the estimator's own state as it was)
_MODULES: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()
ONNX_OPSET = 17


class GRUNet(NamedTuple):
    """A trained GRU + MLP head, everything inference needs (float32, torch's layout).

    GRU weights are row blocks (r, z, n); ``layers`` are ``(weight (out, in), bias (out,))`` with
    ReLU between them; regression outputs are ``raw * y_scale + y_mean`` (``classes`` None);
    ``reverse`` reads the steps last to first.
    """

    w_ih: np.ndarray
    w_hh: np.ndarray
    b_ih: np.ndarray
    b_hh: np.ndarray
    layers: tuple[tuple[np.ndarray, np.ndarray], ...]
    n_channels: int
    n_steps: int
    y_mean: float = 0.0
    y_scale: float = 1.0
    classes: np.ndarray | None = None
    reverse: bool = False

    @property
    def hidden(self) -> int:
        """GRU cells."""
        return int(self.w_hh.shape[1])


def require_torch() -> Any:
    """The torch module, imported lazily (a PerceptionError when it is not installed)."""
    try:
        import torch
    except ImportError as err:
        raise PerceptionError(
            "The 'gru' model needs torch, which is an optional extra and is not installed "
            "(pip install -r requirements/train.txt). Use svm_rbf, svm_linear or mlp instead."
        ) from err
    return torch


def torch_available() -> bool:
    """Whether torch is installed, looked up without the 3.5 s import."""
    return importlib.util.find_spec("torch") is not None


class GRUEstimator(BaseEstimator):
    """16 GRU cells then an MLP (16, 8), trained with Adam and weight decay.

    ``n_channels`` is the first axis of the flattened features, the rest is time.
    ``reverse_time`` reads the window backwards, so the final hidden state the MLP reads is nearest
    the onset, where a tap's position is carried. ``validation_fraction`` > 0 holds out a share for
    early stopping (``patience`` epochs; never below 20 samples); 0 trains ``max_epochs`` on
    everything, which measured better with weight decay. ``input_scaling`` standardises the inputs
    while training (``global``: per-channel mean, one scale; ``channel``; ``none``; ``auto``: none
    when their RMS is in :data:`AUTO_UNSCALED_RMS`, else global), folded into the input weights
    afterwards. ``n_threads`` pins torch's CPU threads.
    """

    def __init__(
        self,
        regression: bool = True,
        n_channels: int = 80,
        hidden: int = 16,
        max_epochs: int = 60,
        patience: int = 15,
        batch_size: int = 32,
        lr: float = 3e-3,
        weight_decay: float = 3e-3,
        reverse_time: bool = True,
        validation_fraction: float = 0.0,
        input_scaling: str = "auto",
        n_threads: int = 1,
        random_state: int = 0,
    ) -> None:
        self.regression = regression
        self.n_channels = n_channels
        self.hidden = hidden
        self.max_epochs = max_epochs
        self.patience = patience
        self.batch_size = batch_size
        self.lr = lr
        self.weight_decay = weight_decay
        self.reverse_time = reverse_time
        self.validation_fraction = validation_fraction
        self.input_scaling = input_scaling
        self.n_threads = n_threads
        self.random_state = random_state

    def __sklearn_tags__(self):
        """A regressor or a classifier as ``regression`` says; either needs its target."""
        tags = super().__sklearn_tags__()
        tags.estimator_type = "regressor" if self.regression else "classifier"
        tags.target_tags.required = True
        if self.regression:
            tags.regressor_tags = RegressorTags()
        else:
            tags.classifier_tags = ClassifierTags()
        return tags

    def _check_params(self, n_features: int) -> int:
        for name in ("n_channels", "hidden", "max_epochs", "batch_size", "n_threads"):
            v = getattr(self, name)
            if not isinstance(v, (int, np.integer)) or v < 1:
                raise PerceptionError(
                    f"The {name!r} parameter must be an integer >= 1. Got {v!r} instead."
                )
        for name in ("lr", "weight_decay"):
            v = getattr(self, name)
            if (
                not isinstance(v, (int, float))
                or not np.isfinite(v)
                or v < 0
                or (name == "lr" and v == 0)
            ):
                raise PerceptionError(
                    f"The {name!r} parameter must be a finite number "
                    f"{'> 0' if name == 'lr' else '>= 0'}. Got {v!r} instead."
                )
        if not 0.0 <= float(self.validation_fraction) < 0.5:
            raise PerceptionError(
                "The 'validation_fraction' parameter must be in [0, 0.5). Got "
                f"{self.validation_fraction!r} instead."
            )
        if n_features % self.n_channels:
            raise PerceptionError(
                f"The 'n_channels' parameter ({self.n_channels}) must divide the number of "
                f"features (channel-major series). Got {n_features} features instead."
            )
        return n_features // self.n_channels

    def _seq(self, X: np.ndarray, n_steps: int) -> np.ndarray:
        """``(n, n_channels * n_steps)`` -> ``(n, n_steps, n_channels)`` float32."""
        x = np.asarray(X, dtype=np.float32)
        if x.ndim != 2 or x.shape[1] != self.n_channels * n_steps:
            raise PerceptionError(
                f"The 'X' parameter must have shape (n, {self.n_channels * n_steps}). "
                f"Got {x.shape} instead."
            )
        if not np.isfinite(x).all():
            raise PerceptionError("The 'X' parameter must be finite. Got NaN or inf instead.")
        return np.ascontiguousarray(x.reshape(len(x), self.n_channels, n_steps).transpose(0, 2, 1))

    def _input_scaling(self, seq: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Per-channel mean and scale of ``(n, n_steps, n_channels)`` training inputs."""
        c = seq.shape[2]
        mode = self.input_scaling
        mean = seq.mean(axis=(0, 1), dtype=np.float64)
        if mode == "auto":
            rms = float(np.sqrt(np.mean((seq - mean) ** 2, dtype=np.float64)))
            mode = "none" if AUTO_UNSCALED_RMS[0] <= rms <= AUTO_UNSCALED_RMS[1] else "global"
        if mode == "none":
            return np.zeros(c), np.ones(c)
        if mode == "channel":
            scale = seq.std(axis=(0, 1), dtype=np.float64)
        elif mode == "global":
            scale = np.full(c, np.sqrt(np.mean((seq - mean) ** 2, dtype=np.float64)))
        else:
            raise PerceptionError(
                "The 'input_scaling' parameter must be 'auto', 'global', 'channel' or 'none'. Got "
                f"{self.input_scaling!r} instead."
            )
        scale[~(scale > 1e-12)] = 1.0
        return mean, scale

    def fit(self, X: np.ndarray, y: np.ndarray) -> GRUEstimator:
        """Train on features ``(n, n_channels * n_steps)`` (PerceptionError: no torch or bad X)."""
        torch = require_torch()
        X, y = validated(self, X, y, reset=True, dtype=np.float32, y_numeric=self.regression)
        if not self.regression:
            try:
                check_classification_targets(y)
            except ValueError as err:
                raise PerceptionError(str(err)) from err
        n_steps = self._check_params(X.shape[1])
        seq = self._seq(X, n_steps)
        x_mean, x_scale = self._input_scaling(seq)
        seq = ((seq - x_mean) / x_scale).astype(np.float32)
        if self.reverse_time:
            seq = seq[:, ::-1].copy()  # (a view of one step keeps its negative stride)
        y = np.asarray(y)
        if self.regression:
            yf = y.astype(np.float64)
            y_mean = float(yf.mean())
            y_scale = float(yf.std()) or 1.0
            target = ((yf - y_mean) / y_scale).astype(np.float32)[:, None]
            classes = None
        else:
            classes, idx = np.unique(y, return_inverse=True)
            target = idx.astype(np.int64)
            y_mean, y_scale = 0.0, 1.0
        n_out = 1 if classes is None else len(classes)
        rng = np.random.default_rng(self.random_state)
        n = len(seq)
        order = rng.permutation(n)
        n_val = round(n * float(self.validation_fraction)) if n >= 20 else 0
        val, train = order[:n_val], order[n_val:]
        old_threads = torch.get_num_threads()
        torch.set_num_threads(int(self.n_threads))
        try:
            torch.manual_seed(self.random_state)
            gru = torch.nn.GRU(self.n_channels, self.hidden, batch_first=True)
            head = torch.nn.Sequential(
                torch.nn.Linear(self.hidden, 16),
                torch.nn.ReLU(),
                torch.nn.Linear(16, 8),
                torch.nn.ReLU(),
                torch.nn.Linear(8, n_out),
            )
            params = list(gru.parameters()) + list(head.parameters())
            opt = torch.optim.Adam(params, lr=self.lr, weight_decay=float(self.weight_decay))
            loss_fn = torch.nn.MSELoss() if self.regression else torch.nn.CrossEntropyLoss()
            xs, ts = torch.from_numpy(seq), torch.from_numpy(target)

            def loss_of(idx: np.ndarray):
                _, h = gru(xs[idx])
                return loss_fn(head(h[-1]), ts[idx])

            best, best_state, wait, epochs = np.inf, None, 0, 0
            for _ in range(int(self.max_epochs)):
                epochs += 1
                for start in range(0, len(train), int(self.batch_size)):
                    idx = train[start : start + int(self.batch_size)]
                    opt.zero_grad()
                    loss = loss_of(idx)
                    loss.backward()
                    torch.nn.utils.clip_grad_norm_(params, 1.0)
                    opt.step()
                train = rng.permutation(train)
                if n_val:
                    with torch.no_grad():
                        v = float(loss_of(val))
                    if v < best - 1e-6:
                        best, wait = v, 0
                        best_state = [p.detach().clone() for p in params]
                    else:
                        wait += 1
                        if wait >= self.patience:
                            break
            if best_state is not None:
                with torch.no_grad():
                    for p, b in zip(params, best_state, strict=True):
                        p.copy_(b)
        finally:
            torch.set_num_threads(old_threads)
        lin = [m for m in head if isinstance(m, torch.nn.Linear)]
        # W (x - m) / s + b = (W / s) x + (b - W m / s): the network takes unscaled inputs
        w_ih = gru.weight_ih_l0.detach().numpy().astype(np.float64)
        b_ih = gru.bias_ih_l0.detach().numpy().astype(np.float64)
        self.net_ = GRUNet(
            w_ih=(w_ih / x_scale).astype(np.float32),
            w_hh=gru.weight_hh_l0.detach().numpy().copy(),
            b_ih=(b_ih - w_ih @ (x_mean / x_scale)).astype(np.float32),
            b_hh=gru.bias_hh_l0.detach().numpy().copy(),
            layers=tuple(
                (m.weight.detach().numpy().copy(), m.bias.detach().numpy().copy()) for m in lin
            ),
            n_channels=int(self.n_channels),
            n_steps=int(n_steps),
            y_mean=y_mean,
            y_scale=y_scale,
            classes=classes,
            reverse=bool(self.reverse_time),
        )
        if classes is not None:
            self.classes_ = classes
        self.n_epochs_ = epochs
        self.best_val_loss_ = float(best)
        self.onnx_ = self._export()
        return self

    def _export(self) -> bytes:
        """The network as ONNX by torch's TorchScript exporter (offline, no onnxscript).

        Input ``(n, n_channels * n_steps)`` float32; output ``(n, 1)`` estimates or ``(n,
        n_classes)`` probabilities in ``classes_`` order.
        """
        torch = require_torch()
        net, (gru, head) = self.net_, self._modules()
        c, t = int(net.n_channels), int(net.n_steps)

        class Network(torch.nn.Module):
            def __init__(self) -> None:
                super().__init__()
                self.gru, self.head = gru, head

            def forward(self, x):
                seq = x.reshape(-1, c, t).transpose(1, 2)  # channel-major features -> steps
                _, h = self.gru(torch.flip(seq, dims=[1]) if net.reverse else seq)
                out = self.head(h[-1])
                if net.classes is not None:
                    return torch.softmax(out, dim=1)
                return out * net.y_scale + net.y_mean

        buf = io.BytesIO()
        with warnings.catch_warnings():  # the exporter's deprecation and tracer notes
            warnings.simplefilter("ignore")
            torch.onnx.export(
                Network().eval(),
                (torch.zeros(1, c * t),),
                buf,
                dynamo=False,
                input_names=["features"],
                output_names=["out"],
                dynamic_axes={"features": {0: "n"}, "out": {0: "n"}},
                opset_version=ONNX_OPSET,
            )
        return buf.getvalue()

    def _modules(self):
        """Torch modules rebuilt from the NumPy weights (cached in ``_MODULES``)."""
        cached = _MODULES.get(self)
        if cached is not None and cached[0] is self.net_:
            return cached[1]
        torch = require_torch()
        net = self.net_
        gru = torch.nn.GRU(int(net.n_channels), net.hidden, batch_first=True)
        layers = []
        for i, (w, b) in enumerate(net.layers):
            lin = torch.nn.Linear(w.shape[1], w.shape[0])
            with torch.no_grad():
                lin.weight.copy_(torch.from_numpy(np.asarray(w, np.float32)))
                lin.bias.copy_(torch.from_numpy(np.asarray(b, np.float32)))
            layers.append(lin)
            if i < len(net.layers) - 1:
                layers.append(torch.nn.ReLU())
        pairs = {"weight_ih_l0": net.w_ih, "weight_hh_l0": net.w_hh}
        pairs.update({"bias_ih_l0": net.b_ih, "bias_hh_l0": net.b_hh})
        with torch.no_grad():
            for name, arr in pairs.items():
                getattr(gru, name).copy_(torch.from_numpy(np.asarray(arr, np.float32)))
        mods = (gru.eval(), torch.nn.Sequential(*layers).eval())
        _MODULES[self] = (net, mods)
        return mods

    def _forward(self, X: np.ndarray) -> np.ndarray:
        check_is_fitted(self, "net_")
        torch = require_torch()
        X = validated(self, X, reset=False, dtype=np.float32)
        seq = self._seq(X, int(self.net_.n_steps))
        if self.net_.reverse:
            seq = seq[:, ::-1].copy()  # (a view of one step keeps its negative stride)
        gru, head = self._modules()
        old_threads = torch.get_num_threads()
        torch.set_num_threads(int(self.n_threads))
        try:
            with torch.no_grad():
                _, h = gru(torch.from_numpy(seq))
                return head(h[-1]).numpy().astype(np.float64)
        finally:
            torch.set_num_threads(old_threads)

    def predict(self, X: np.ndarray) -> np.ndarray:
        """Positions (regression) or class labels for ``(n, n_channels * n_steps)`` features."""
        out = self._forward(X)
        if self.regression:
            return out[:, 0] * self.net_.y_scale + self.net_.y_mean
        return self.classes_[out.argmax(axis=1)]

    def score(self, X: np.ndarray, y: np.ndarray, sample_weight: np.ndarray | None = None) -> float:
        """R^2 of the predictions (regression) or their accuracy (classes), as scikit-learn's."""
        mixin = RegressorMixin if self.regression else ClassifierMixin
        return mixin.score(self, X, y, sample_weight)

    @available_if(lambda self: not self.regression)
    def predict_proba(self, X: np.ndarray) -> np.ndarray:
        """Softmax class probabilities ``(n, n_classes)`` (a classifier's only)."""
        out = self._forward(X)
        e = np.exp(out - out.max(axis=1, keepdims=True))
        return e / e.sum(axis=1, keepdims=True)
