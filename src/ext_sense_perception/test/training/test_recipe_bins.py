"""The recipe's feature bins: a tap bundle on Gaussian bins exports, serves and retrains alike."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from ext_sense_perception.data.sources import from_sim_dataset
from ext_sense_perception.online.predictor import load_model
from ext_sense_perception.training.calibration import recipe_of
from ext_sense_perception.training.recipe import Recipe, train_bundle
from ext_sense_runtime.stamps import MS


@pytest.fixture(scope="module")
def gauss_bundle(tap_npz: Path, tmp_path_factory: pytest.TempPathFactory):
    ws = from_sim_dataset(tap_npz)
    out = tmp_path_factory.mktemp("gauss_tap")
    card = train_bundle(ws, out, Recipe(anytime_post_ns=(100 * MS,)))
    return out, card, ws


def test_a_tap_bundle_bins_with_gauss_and_its_backends_agree(gauss_bundle):
    out, card, ws = gauss_bundle
    assert card.feature_params["bin_kernel"] == "gauss"
    x = ws.X.reshape(len(ws.y), -1)
    onnx, skl = load_model(out, "onnx"), load_model(out, "sklearn")
    a, _ = onnx.raw_predict(x)
    b, _ = skl.raw_predict(x)
    np.testing.assert_allclose(a, b, rtol=1e-4, atol=1e-6)
    assert np.mean(np.abs(b - ws.y)) < 0.5 * np.mean(np.abs(ws.y - ws.y.mean()))
    assert len(onnx.anytime) == 1
    for fast in onnx.anytime:  # the anytime models bin alike
        assert fast.card.feature_params["bin_kernel"] == "gauss"


def test_recipe_of_a_card_keeps_its_kernel(gauss_bundle):
    _, card, _ = gauss_bundle
    assert recipe_of(card).bin_kernel == "gauss"
    params = {k: v for k, v in card.feature_params.items() if k != "bin_kernel"}
    older = dataclasses.replace(card, feature_params=params)
    assert recipe_of(older).bin_kernel == "box"  # cards from before the kernel: box bins
