"""Models, the paper's protocol, the training recipe and ONNX export: the only training stack."""
