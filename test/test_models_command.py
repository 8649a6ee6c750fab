"""``ext-sense models create|list``: the default models, written where the graphs look first."""

from __future__ import annotations

import contextlib
import io

import pytest
from sim_models import write_card

from ext_sense import cli
from ext_sense.commands import demo, models


@pytest.fixture
def store(tmp_path, monkeypatch):
    """An empty user data directory, no $EXT_SENSE_MODELS, an unrelated working directory."""
    monkeypatch.delenv("EXT_SENSE_MODELS", raising=False)
    monkeypatch.setenv("XDG_DATA_HOME", str(tmp_path / "data"))
    (tmp_path / "cwd").mkdir()
    monkeypatch.chdir(tmp_path / "cwd")
    return tmp_path / "data" / "ext_sense" / "models"


def _main(*argv: str) -> tuple[int, str]:
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        rc = cli.main(list(argv))
    return rc, out.getvalue()


def test_create_trains_every_task_through_the_project_paths(store, monkeypatch, tmp_path):
    calls = []

    def fake_ensure(model_dir, sensor, trials, retrain=False, log=None):
        calls.append(("stream", model_dir, sensor, trials, retrain))
        write_card(model_dir, "tap_localization", sensor)
        return 0

    def fake_simulated(model_dir, task, sensor, trials, force, log):
        calls.append(("recipe", model_dir, sensor, trials, force))
        write_card(model_dir, task, sensor)
        return 0

    monkeypatch.setattr(demo, "ensure_model", fake_ensure)
    monkeypatch.setattr(models, "train_simulated", fake_simulated)
    rc, out = _main("models", "create")
    assert rc == 0
    assert calls == [
        ("stream", store / "tap_localization_nuskin", "nuskin", 300, False),
        ("recipe", store / "handover_stability_nuskin", "nuskin", 400, False),
        ("recipe", store / "food_identification_nuskin", "nuskin", 70, False),
    ]
    assert str(store) in out
    assert not any((tmp_path / "cwd").iterdir())

    calls.clear()
    rc, _ = _main("models", "create", "--out", str(tmp_path / "o"), "--task", "handover_stability")
    assert rc == 0
    assert calls == [("recipe", tmp_path / "o" / "handover_stability_nuskin", "nuskin", 400, False)]

    rc, out = _main("models", "list")
    assert rc == 0
    assert f"2. user data {store}" in out
    assert f"tap_localization/nuskin      -> {store / 'tap_localization_nuskin'}" in out
    assert "tap_localization/biotac      -> not found" in out


def test_train_simulated_trains_the_recipe_and_keeps_a_current_model(store, tmp_path):
    from ext_sense_perception.online.model_card import read_card

    log = io.StringIO()
    out = tmp_path / "handover"
    assert models.train_simulated(out, "handover_stability", "nuskin", 16, False, log) == 0
    card = read_card(out)
    assert (card.task, card.sensor) == ("handover_stability", "nuskin")
    # cut from the device stream, and again by each late reader: windows of up to 16 trials
    copies = models.HANDOVER_LATE_READS + 1
    assert card.n_train % copies == 0
    assert 16 * copies * 0.8 <= card.n_train <= 16 * copies
    assert f"stream, {models.HANDOVER_LATE_READS} late reads: {card.n_train} windows" in (
        log.getvalue()
    )
    assert (out / "model.onnx").is_file()
    assert models.train_simulated(out, "handover_stability", "nuskin", 16, False, log) == 0
    assert "keeping" in log.getvalue()
    assert read_card(out).id == card.id
