# ruff: noqa: N803  (X / F for sample matrices, as in scikit-learn)
"""GRU(16) + MLP(16, 8) estimator on the binned series (torch, optional extra).

torch is imported only in :meth:`GRUEstimator.fit`; without it the model gives a clear
:class:`PerceptionError`. The GRU runs over the time axis of the features' output reshaped to
``(n, n_channels, n_steps)`` when ``n_channels`` is set, else over one channel.
"""

from __future__ import annotations

import numpy as np
from sklearn.base import BaseEstimator

from ext_sense_perception.errors import PerceptionError


def _torch():
    try:
        import torch
    except ImportError as err:
        raise PerceptionError(
            "The 'gru' model needs torch, which is an optional extra and is not installed "
            "(pip install torch). Use svm_rbf, svm_linear or mlp instead."
        ) from err
    return torch


class GRUEstimator(BaseEstimator):
    """16 GRU cells then an MLP (16, 8), trained with Adam.

    Args:
        regression: Regression (MSE) or classification (cross-entropy).
        n_channels: Channels of the flattened feature vector (its first axis).
        hidden: GRU cells.
        epochs: Training epochs.
        lr: Learning rate.
        random_state: Seed.
    """

    def __init__(
        self,
        regression: bool = True,
        n_channels: int = 80,
        hidden: int = 16,
        epochs: int = 200,
        lr: float = 1e-2,
        random_state: int = 0,
    ) -> None:
        self.regression = regression
        self.n_channels = n_channels
        self.hidden = hidden
        self.epochs = epochs
        self.lr = lr
        self.random_state = random_state

    def _seq(self, X: np.ndarray):
        torch = _torch()
        x = np.asarray(X, dtype=np.float32)
        c = self.n_channels if x.shape[1] % self.n_channels == 0 else 1
        return torch.from_numpy(x.reshape(len(x), c, -1).transpose(0, 2, 1).copy())

    def fit(self, X: np.ndarray, y: np.ndarray) -> GRUEstimator:
        """Train on flattened features ``(n, n_channels * n_steps)``."""
        torch = _torch()
        torch.manual_seed(self.random_state)
        seq = self._seq(X)
        if self.regression:
            target = torch.tensor(np.asarray(y, np.float32))[:, None]
            n_out = 1
        else:
            self.classes_, idx = np.unique(y, return_inverse=True)
            target = torch.tensor(idx)
            n_out = len(self.classes_)
        gru = torch.nn.GRU(seq.shape[2], self.hidden, batch_first=True)
        head = torch.nn.Sequential(
            torch.nn.Linear(self.hidden, 16),
            torch.nn.ReLU(),
            torch.nn.Linear(16, 8),
            torch.nn.ReLU(),
            torch.nn.Linear(8, n_out),
        )
        params = list(gru.parameters()) + list(head.parameters())
        opt = torch.optim.Adam(params, lr=self.lr)
        loss_fn = torch.nn.MSELoss() if self.regression else torch.nn.CrossEntropyLoss()
        for _ in range(self.epochs):
            opt.zero_grad()
            _, h = gru(seq)
            loss = loss_fn(head(h[-1]), target)
            loss.backward()
            opt.step()
        self.gru_, self.head_ = gru, head
        return self

    def _forward(self, X: np.ndarray) -> np.ndarray:
        torch = _torch()
        if not hasattr(self, "gru_"):
            raise PerceptionError("This GRUEstimator is not fitted yet: call fit() first.")
        with torch.no_grad():
            _, h = self.gru_(self._seq(X))
            return self.head_(h[-1]).numpy()

    def predict(self, X: np.ndarray) -> np.ndarray:
        """Positions (regression) or class labels."""
        out = self._forward(X)
        if self.regression:
            return out[:, 0].astype(np.float64)
        return self.classes_[out.argmax(axis=1)]

    def predict_proba(self, X: np.ndarray) -> np.ndarray:
        """Softmax class probabilities."""
        out = self._forward(X)
        e = np.exp(out - out.max(axis=1, keepdims=True))
        return e / e.sum(axis=1, keepdims=True)
