"""Feature sets of contact windows as scikit-learn transformers, one estimator per family.

Each family is a fixed linear map along the window's time axis followed by at most a few
element-wise steps, so :mod:`ext_sense_perception.training.onnx_export` expresses it in ONNX.
"""
