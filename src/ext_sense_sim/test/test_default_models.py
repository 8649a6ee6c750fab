"""The default models: kept while their inputs are current, trained through the project's paths."""

from __future__ import annotations

import pytest

from ext_sense_perception.online.model_card import read_card
from ext_sense_perception.training.bundle_io import LOCK_FILE
from ext_sense_sim import default_models


class _Set:
    y = ()


@pytest.fixture
def fake_training(monkeypatch):
    """Training that records its inputs and writes a card only (the cache logic, not the fit)."""
    calls = []

    def training_set(task, sensor, scene, trials, log):
        calls.append((task, scene, trials))
        return _Set(), None

    def train_bundle(ws, out, recipe):
        (out / "model_card.json").write_text("{}")
        return type("Card", (), {"id": "fake", "metrics": {}})()

    monkeypatch.setattr(default_models, "training_set", training_set)
    monkeypatch.setattr(default_models, "train_bundle", train_bundle)
    return calls


def test_cached_model_is_reused_only_with_a_matching_fingerprint(tmp_path, fake_training):
    lines: list[str] = []
    model = tmp_path / "models" / "tap_localization_nuskin"
    ensure = default_models.ensure_model
    assert ensure(model, "tap_localization", "nuskin", 50, log=lines.append)
    assert fake_training == [("tap_localization", "tap_rod30_nuskin", 50)]
    assert not ensure(model, "tap_localization", "nuskin", 50, log=lines.append)
    assert len(fake_training) == 1
    assert any(line.startswith("using model") for line in lines)

    (model / default_models.FINGERPRINT_FILE).write_text("trained-elsewhere\n")
    assert ensure(model, "tap_localization", "nuskin", 50, log=lines.append)
    assert len(fake_training) == 2
    assert any("retraining" in line for line in lines)
    assert ensure(model, "tap_localization", "nuskin", 50, force=True)
    assert len(fake_training) == 3
    # only the bundle and the place's lock: no staged or replaced copies left beside it
    assert sorted(p.name for p in model.parent.iterdir()) == [LOCK_FILE, model.name]


def test_fingerprint_follows_scene_and_settings():
    fp = default_models.training_fingerprint
    base = fp("nuskin", "tap_rod30_nuskin", 300, "stream")
    assert base == fp("nuskin", "tap_rod30_nuskin", 300, "stream")
    assert base != fp("nuskin", "tap_rod20_nuskin", 300, "stream")
    assert base != fp("nuskin", "tap_rod30_nuskin", 100, "stream")
    assert base != fp("nuskin", "tap_rod30_nuskin", 300, "dataset")


def test_the_nuskin_handover_trains_on_ideal_and_late_reads_and_is_kept(tmp_path):
    lines: list[str] = []
    out = tmp_path / "handover"
    assert default_models.ensure_model(out, "handover_stability", "nuskin", 16, log=lines.append)
    card = read_card(out)
    assert (card.task, card.sensor) == ("handover_stability", "nuskin")
    # cut from the device stream, and again by each late reader: windows of up to 16 trials
    copies = default_models.HANDOVER_LATE_READS + 1
    assert card.n_train % copies == 0
    assert 16 * copies * 0.8 <= card.n_train <= 16 * copies
    assert f"simulated {card.n_train} windows" in "\n".join(lines)
    assert (out / "model.onnx").is_file()
    assert not default_models.ensure_model(out, "handover_stability", "nuskin", 16)
    assert read_card(out).id == card.id
