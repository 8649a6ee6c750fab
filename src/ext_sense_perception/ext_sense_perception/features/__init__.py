"""Feature families of contact windows: scikit-learn transformers that ONNX export can express."""
