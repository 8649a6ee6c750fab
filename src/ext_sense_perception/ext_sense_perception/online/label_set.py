"""A session's label set: the classes a model's decisions are restricted to (no ROS).

A model trained on several days knows more classes than one session (today's plate) holds.
"""

from __future__ import annotations

import numpy as np

from ext_sense_perception.errors import PerceptionError


def restrict(proba: np.ndarray, classes: tuple[str, ...], allowed: tuple[str, ...]) -> np.ndarray:
    """A copy of ``proba`` with the classes outside ``allowed`` (empty: all) at 0, renormalised.

    PerceptionError: no allowed class is one of the model's.
    """
    p = np.array(proba, dtype=np.float64, copy=True)
    if not allowed:
        return p
    keep = np.isin(np.asarray(classes), np.asarray(allowed))
    if not keep.any():
        raise PerceptionError(
            f"The label set {list(allowed)} has no class of the model's {list(classes)}."
        )
    p[:, ~keep] = 0.0
    total = p.sum(axis=1, keepdims=True)
    flat = total[:, 0] <= 0  # every allowed class at probability 0: spread evenly among them
    p[flat] = keep / keep.sum()
    total[flat] = 1.0
    return p / total
