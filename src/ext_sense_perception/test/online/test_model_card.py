"""Model cards checked on load: against their schema, the loader's task and sensor, the model."""

from __future__ import annotations

import json
import shutil
from collections.abc import Callable
from pathlib import Path

import pytest

from ext_sense_perception.data.sources import from_sim_dataset
from ext_sense_perception.errors import PerceptionError
from ext_sense_perception.online.model_card import read_card
from ext_sense_perception.online.predictor import load_model
from ext_sense_perception.training.bundle_io import save_bundle
from ext_sense_perception.training.fit import fit_anytime, fit_model
from ext_sense_runtime.stamps import MS


@pytest.fixture(scope="module")
def tap_bundle(tap_npz: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    ws = from_sim_dataset(tap_npz)
    anytime = fit_anytime(ws, "fft", "svm_linear", (50 * MS,))
    return save_bundle(fit_model(ws, "fft", "svm_linear"), tmp_path_factory.mktemp("tap"), anytime)


@pytest.fixture(scope="module")
def food_bundle(food_npz: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    ws = from_sim_dataset(food_npz)
    return save_bundle(fit_model(ws, "fft", "svm"), tmp_path_factory.mktemp("food"))


def _spoiled(bundle: Path, tmp_path: Path, change: Callable[[dict], None]) -> Path:
    """A copy of the bundle whose card ``change`` edited in place."""
    out = tmp_path / "bundle"
    shutil.copytree(bundle, out)
    card = json.loads((out / "model_card.json").read_text())
    change(card)
    (out / "model_card.json").write_text(json.dumps(card))
    return out


def _set(path: str, value: object) -> Callable[[dict], None]:
    def change(card: dict) -> None:
        *parents, key = path.split(".")
        for p in parents:
            card = card[p]
        card[key] = value

    return change


@pytest.mark.parametrize(
    ("path", "value", "match"),
    [
        ("class_names", ["near", "far"], r"'class_names' must be empty: tap_localization is a"),
        ("window.period_ns", 0, r"'window.period_ns' must be positive\. Got 0"),
        ("window.period_ns", 1.5, r"'window.period_ns' must be an integer\. Got float 1.5"),
        ("window.n_channels", -80, r"'window.n_channels' must be positive"),
        ("window.pre_ns", 60 * MS, r"'window.pre_ns' must be <= the profile's pre_ns"),
        ("window.sensor", "biotac", r"'window.sensor' must be the card's sensor 'nuskin'"),
        ("profile.sample_ns", 0, r"'sample_ns' parameter must be in \(0, 1 s\]"),
        ("profile.post_ns", 200 * MS, r"'window' must end within the profile's \(0, 200000000\]"),
        ("rate_hz", 0, r"'rate_hz' must be a positive number of Hz\. Got 0"),
        ("rate_hz", "4000", r"'rate_hz' must be int or float\. Got str '4000'"),
        ("anytime_post_ms", [-5.0], r"'anytime_post_ms' must be each in \(0, 250\) ms"),
        ("anytime_post_ms", ["50"], r"'anytime_post_ms' must be a list of numbers"),
        ("n_train", True, r"'n_train' must be int\. Got a bool True"),
        ("metrics.cv_mae_m", "0.02", r"'metrics.cv_mae_m' must be a number"),
        ("task", "food_identification", r"profile is for 'tap_localization'"),
    ],
)
def test_a_card_breaking_its_schema_is_refused_with_the_field_named(
    tap_bundle, tmp_path, path, value, match
):
    bad = _spoiled(tap_bundle, tmp_path, _set(path, value))
    with pytest.raises(PerceptionError, match=match):
        read_card(bad)
    with pytest.raises(PerceptionError, match=r"model_card.json' is corrupt"):
        load_model(bad)


@pytest.mark.parametrize(
    ("value", "match"),
    [
        ("apple", r"'class_names' must be list\. Got str 'apple'"),  # not 'a', 'p', 'p', ...
        (["apple"], r"at least 2 distinct names: food_identification is a classification task"),
        (["apple", "apple", "tofu"], r"at least 2 distinct names"),
        ([], r"at least 2 distinct names"),
        (["apple", 3], r"a list of non-empty strings\. Got int 3"),
    ],
)
def test_class_names_of_the_wrong_kind_are_refused(food_bundle, tmp_path, value, match):
    bad = _spoiled(food_bundle, tmp_path, _set("class_names", value))
    with pytest.raises(PerceptionError, match=match):
        read_card(bad)


@pytest.mark.parametrize("backend", ["onnx", "sklearn"])
@pytest.mark.parametrize(
    "names", [["apple", "tofu"], ["apple", "tofu", "water", "bread"], ["tofu", "apple", "water"]]
)
def test_class_names_that_do_not_match_the_model_are_refused(food_bundle, tmp_path, backend, names):
    assert list(read_card(food_bundle).class_names) == ["apple", "tofu", "water"]
    bad = _spoiled(food_bundle, tmp_path, _set("class_names", names))
    read_card(bad)  # a valid card on its own
    match = rf"The model '.*model\.(onnx|joblib)' .*; its card names {len(names)} classes"
    with pytest.raises(PerceptionError, match=match):
        load_model(bad, backend)


@pytest.mark.parametrize("backend", ["onnx", "sklearn"])
def test_a_classifier_described_as_regression_is_refused(food_bundle, tmp_path, backend):
    """The food model under a card that says tap localisation (regression, no classes)."""

    def as_tap(card: dict) -> None:
        card["task"] = card["profile"]["task"] = "tap_localization"
        card["class_names"] = []

    bad = _spoiled(food_bundle, tmp_path, as_tap)
    assert read_card(bad).is_regression
    with pytest.raises(PerceptionError, match=r"its card says regression"):
        load_model(bad, backend)


def test_a_model_for_another_task_or_sensor_is_refused(tap_bundle):
    assert load_model(tap_bundle, "onnx", "tap", "nuskin").task == "tap_localization"
    with pytest.raises(
        PerceptionError,
        match=r"is a tap_localization/nuskin model; this node "
        r"serves food_identification/nuskin",
    ):
        load_model(tap_bundle, "onnx", "food_identification", "nuskin")
    with pytest.raises(PerceptionError, match=r"serves tap_localization/biotac"):
        load_model(tap_bundle, "sklearn", "tap_localization", "biotac")


def test_an_anytime_model_that_does_not_fit_its_place_is_refused(tap_bundle, tmp_path):
    bad = tmp_path / "bundle"
    shutil.copytree(tap_bundle, bad)
    sub = bad / "anytime" / "post_50ms"
    shutil.rmtree(sub)
    shutil.copytree(tap_bundle, sub, ignore=shutil.ignore_patterns("anytime"))  # a 250 ms model
    card = json.loads((sub / "model_card.json").read_text())
    card["anytime_post_ms"] = []
    (sub / "model_card.json").write_text(json.dumps(card))
    with pytest.raises(PerceptionError, match=r"post_50ms' must end 50 ms after the onset"):
        load_model(bad)
