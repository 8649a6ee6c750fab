"""The recipe's feature bins and taper: a tap bundle on Gaussian bins with tapered ends exports,
serves and retrains alike."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from ext_sense_perception.data.sources import from_sim_dataset
from ext_sense_perception.online.predictor import load_model
from ext_sense_perception.training.calibration import recipe_of
from ext_sense_perception.training.recipe import Recipe, resolve, train_bundle
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
    assert card.feature_params["taper"] == 0.2
    x = ws.X.reshape(len(ws.y), -1)
    onnx, skl = load_model(out, "onnx"), load_model(out, "sklearn")
    a, _ = onnx.raw_predict(x)
    b, _ = skl.raw_predict(x)
    np.testing.assert_allclose(a, b, rtol=1e-4, atol=1e-6)
    assert np.mean(np.abs(b - ws.y)) < 0.5 * np.mean(np.abs(ws.y - ws.y.mean()))
    assert len(onnx.anytime) == 1
    for fast in onnx.anytime:  # the anytime models bin alike
        assert fast.card.feature_params["bin_kernel"] == "gauss"
        assert fast.card.feature_params["taper"] == 0.2


def test_recipe_of_a_card_keeps_its_kernel_and_taper(gauss_bundle):
    _, card, _ = gauss_bundle
    assert recipe_of(card).bin_kernel == "gauss"
    assert recipe_of(card).taper == 0.2
    params = {k: v for k, v in card.feature_params.items() if k not in ("bin_kernel", "taper")}
    older = dataclasses.replace(card, feature_params=params)
    assert recipe_of(older).bin_kernel == "box"  # cards from before the kernel: box bins
    assert recipe_of(older).taper == 0.0  # and from before the taper: none


@pytest.mark.parametrize(("asked", "taper"), [(None, 0.2), (0.0, None), (0.5, 0.5)])
def test_the_recipe_tapers_nuskin_tap_spectra_by_default(tap_npz: Path, asked, taper):
    ws = from_sim_dataset(tap_npz)
    assert resolve(ws, Recipe(taper=asked)).feature_params.get("taper") == taper
    assert "taper" not in resolve(ws, Recipe(features="baseline", taper=asked)).feature_params
    assert "taper" not in resolve(ws._replace(sensor="biotac"), Recipe(taper=asked)).feature_params
