"""``ext-sense models create|list``: the default models, written where the graphs look first."""

from __future__ import annotations

import contextlib
import io

import pytest
from sim_models import write_card

from ext_sense import cli
from ext_sense_sim import default_models


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

    def training_set(task, sensor, scene, trials, log):
        calls.append((task, sensor, scene, trials))
        return type("Set", (), {"y": ()})(), None

    def train_bundle(ws, out, recipe):
        task, sensor = calls[-1][:2]
        write_card(out, task, sensor)
        return type("Card", (), {"id": "fake", "metrics": {}})()

    monkeypatch.setattr(default_models, "training_set", training_set)
    monkeypatch.setattr(default_models, "train_bundle", train_bundle)
    rc, out = _main("models", "create")
    assert rc == 0
    assert calls == [
        ("tap_localization", "nuskin", "tap_rod30_nuskin", 600),
        ("handover_stability", "nuskin", "handover_rod_nuskin", 400),
        ("food_identification", "nuskin", "food_fork_nuskin", 140),
    ]
    assert str(store) in out
    assert not any((tmp_path / "cwd").iterdir())

    calls.clear()
    rc, _ = _main("models", "create")
    assert (rc, calls) == (0, [])  # every model current: kept

    rc, _ = _main("models", "create", "--out", str(tmp_path / "o"), "--task", "handover_stability")
    assert rc == 0
    assert calls == [("handover_stability", "nuskin", "handover_rod_nuskin", 400)]
    assert (tmp_path / "o" / "handover_stability_nuskin" / "model_card.json").is_file()

    rc, out = _main("models", "list")
    assert rc == 0
    assert f"2. user data {store}" in out
    assert f"tap_localization/nuskin      -> {store / 'tap_localization_nuskin'}" in out
    assert "tap_localization/biotac      -> not found" in out
