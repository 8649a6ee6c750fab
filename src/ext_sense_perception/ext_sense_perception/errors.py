"""The one exception type of ext_sense_perception."""

from __future__ import annotations


class PerceptionError(ValueError):
    """Bad input or state in windowing, features, models, importers or evaluation.

    Low-level errors (``OSError``, ``ValueError`` from NumPy, ONNX Runtime failures) are wrapped
    as ``raise PerceptionError(msg) from err`` so callers catch one type. It is a ``ValueError``,
    as scikit-learn's contract asks of parameter errors.
    """
