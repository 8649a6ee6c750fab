# ruff: noqa: N803  (X for sample matrices, as in scikit-learn)
"""Input checks of the project's estimators: scikit-learn's own, raised as PerceptionError (no ROS).

Bad values are a PerceptionError (a ``ValueError``) with scikit-learn's message; input of a
wrong type (sparse, non-numeric) stays scikit-learn's ``TypeError``.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from sklearn.utils.validation import check_array, validate_data

from ext_sense_perception.errors import PerceptionError


def dense_array(X: Any, **kwargs: Any) -> np.ndarray:
    """``X`` through ``sklearn.utils.check_array`` (``kwargs`` are its options).

    Bad values (complex, empty, NaN/inf) raise a PerceptionError with scikit-learn's message; sparse
    input or objects that are not numbers stay scikit-learn's TypeError.
    """
    try:
        return check_array(X, **kwargs)
    except ValueError as err:
        raise PerceptionError(f"The 'X' parameter is not usable: {err}") from err


def validated(estimator: Any, X: Any, y: Any = "no_validation", *, reset: bool, **kwargs: Any):
    """``sklearn.utils.validation.validate_data``: ``X`` (and ``y``) as in :func:`dense_array`.

    ``reset=True`` (``fit``) records ``n_features_in_``; ``reset=False`` checks it. Errors as
    :func:`dense_array`'s (bad columns or target too).
    """
    try:
        return validate_data(estimator, X, y, reset=reset, **kwargs)
    except ValueError as err:
        names = "'X'" if isinstance(y, str) else "'X' or 'y'"
        raise PerceptionError(f"The {names} parameter is not usable: {err}") from err
