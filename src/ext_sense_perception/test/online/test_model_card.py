"""Model cards checked on load: against their schema, the loader's task and sensor, the model."""

from __future__ import annotations

import json
import shutil
from collections.abc import Callable
from pathlib import Path

import pytest

from ext_sense_perception.data.sources import from_sim_dataset
from ext_sense_perception.errors import PerceptionError
from ext_sense_perception.online.model_card import (
    HeldObject,
    object_mismatch,
    object_unknown,
    read_card,
)
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
        ("held_object.length_m", -0.3, r"'held_object.length_m' must be a positive number"),
        ("held_object", {"kind": ""}, r"'held_object' must be \{'kind': str"),
        ("held_object", "rod", r"'held_object' must be dict or null\. Got str 'rod'"),
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


def test_the_card_records_the_rod_it_was_trained_on(tap_bundle, tmp_path):
    card = read_card(tap_bundle)
    assert card.held_object == HeldObject("rod", 0.3)  # the dataset's rod_length_m
    assert json.loads((tap_bundle / "model_card.json").read_text())["held_object"] == {
        "kind": "rod",
        "length_m": 0.3,
    }
    # a card written before the field: read as before, no object known (same id)
    old = _spoiled(tap_bundle, tmp_path, lambda c: c.pop("held_object"))
    assert read_card(old).held_object is None
    assert read_card(old).id == card.id


@pytest.mark.parametrize(
    ("trained", "held", "why"),
    [
        (HeldObject("rod", 0.2), HeldObject("rod", 0.3), "trained on a 20 cm rod, and the graph"),
        (HeldObject("rod", 0.3), HeldObject("fork", 0.19), "trained on a 30 cm rod, and"),
        (HeldObject("rod", 0.3), HeldObject("rod", 0.302), ""),  # within 5 mm
        (HeldObject("rod"), HeldObject("rod", 0.5), ""),  # several lengths: any of them
        (HeldObject("rod", 0.3), HeldObject("rod"), ""),
        (None, HeldObject("rod", 0.3), ""),  # unknown: warned about, not refused
        (HeldObject("rod", 0.3), None, ""),  # the graph names none: nothing to check
    ],
)
def test_a_model_of_another_object_is_a_mismatch(trained, held, why):
    got = object_mismatch(trained, held)
    assert why in got if why else got == ""


def test_a_card_without_an_object_is_accepted_with_a_warning_when_the_graph_names_one():
    note = object_unknown(None, HeldObject("rod", 0.3))
    assert note.startswith("the model card records no held object")
    assert "30 cm rod" in note
    assert object_unknown(HeldObject("rod", 0.3), HeldObject("rod", 0.3)) == ""
    assert object_unknown(None, None) == ""


@pytest.mark.parametrize(
    ("text", "expected"),
    [("rod:0.30", HeldObject("rod", 0.3)), (" fork ", HeldObject("fork")), ("", None)],
)
def test_a_held_object_is_read_from_kind_and_length(text, expected):
    assert HeldObject.parse(text) == expected
    if expected is not None:
        assert HeldObject.parse(expected.to_text()) == expected


@pytest.mark.parametrize(
    ("text", "match"),
    [("rod:-1", "length must be a positive number"), ("rod:x", "positive"), (":0.3", "kind")],
)
def test_a_bad_held_object_is_refused_in_one_line(text, match):
    with pytest.raises(PerceptionError, match=match):
        HeldObject.parse(text)


def test_a_model_of_a_simulator_dataset_records_its_scene_object(food_npz, tmp_path):
    import numpy as np

    from ext_sense_perception.data.window_set import common_held_object, held_object_of

    with np.load(food_npz) as z:
        arrays = {k: z[k] for k in z.files}
    # an older dataset names no object: a rod is told from its rod lengths (the synthetic 0.3)
    assert held_object_of(from_sim_dataset(food_npz)) == HeldObject("rod", 0.3)
    arrays |= {"object_kind": np.array("fork"), "object_length_m": np.array(0.19)}
    np.savez(tmp_path / "fork.npz", **arrays)
    fork = from_sim_dataset(tmp_path / "fork.npz")
    assert held_object_of(fork) == HeldObject("fork", 0.19)
    assert fit_model(fork, "fft", "svm").card.held_object == HeldObject("fork", 0.19)
    longer = fork._replace(held_object=HeldObject("fork", 0.25))
    assert common_held_object([fork, fork]) == HeldObject("fork", 0.19)
    assert common_held_object([fork, longer]) == HeldObject("fork")
    assert common_held_object([fork, longer._replace(held_object=HeldObject("rod", 0.3))]) is None
