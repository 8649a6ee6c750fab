"""What the live graph needs: windows, the window stage, model cards and the runtime predictor.

Nothing here imports scikit-learn's training stack or torch: the inference node loads only this.
"""
