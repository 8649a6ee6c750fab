"""A session's label set: the classes a model's decisions are restricted to (no ROS).

An operator knows which foods are on today's plate; a model trained on several days knows more
classes than one session holds. Restricting the decision to the session's classes (probability
0 outside them, the rest renormalised) is what ``ext-sense score``, the cross-session protocol
and a calibrated bundle's live estimates (its card's ``label_set``) do.
"""

from __future__ import annotations

import numpy as np

from ext_sense_perception.errors import PerceptionError


def restrict(proba: np.ndarray, classes: tuple[str, ...], allowed: tuple[str, ...]) -> np.ndarray:
    """Class probabilities with the classes outside ``allowed`` set to 0, renormalised.

    Args:
        proba: ``(n, n_classes)`` probabilities, columns in ``classes`` order.
        classes: The model's classes.
        allowed: The classes the session may hold (empty: all).

    Returns:
        The restricted probabilities (a copy).

    Raises:
        PerceptionError: when no allowed class is one of the model's.
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
