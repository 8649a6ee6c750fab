"""Models, the paper's protocol, the one training recipe, ONNX export, GRU and taxel stack.

The training stack (scikit-learn, optional torch) lives here and only here; bundles it writes
are served by :mod:`ext_sense_perception.online.predictor` without it.
"""
