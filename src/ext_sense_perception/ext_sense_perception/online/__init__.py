"""What the live graph needs: windows, the window stage and the runtime predictor.

Onset detection and windowing (``window``, ``windowers``), the rclpy-free core of the window node
(``stage``), message conversions (``messages``), the model card (``model_card``), the ONNX / joblib
predictor (``predictor``) and where bundles are found (``model_store``). Nothing here imports
scikit-learn's training stack or torch: the inference node loads only this room and ONNX Runtime.
"""
