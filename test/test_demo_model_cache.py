"""The demo reuses a cached model only when it was trained from what this checkout produces."""

from __future__ import annotations

import io

from ext_sense.commands import demo


def _fake_training(calls):
    def train(model_dir, scene, trials, log):
        calls.append((scene, trials))
        (model_dir / "model_card.json").write_text("{}")
        return 0

    return train


def test_cached_model_is_reused_only_with_a_matching_fingerprint(tmp_path, monkeypatch):
    calls = []
    monkeypatch.setattr(demo, "train_on_stream", _fake_training(calls))
    log = io.StringIO()
    assert demo.ensure_model(tmp_path, "nuskin", 50, log=log) == 0
    assert calls == [("tap_rod30_nuskin", 50)]
    assert demo.ensure_model(tmp_path, "nuskin", 50, log=log) == 0
    assert len(calls) == 1
    assert "using model" in log.getvalue()

    (tmp_path / demo.FINGERPRINT_FILE).write_text("trained-elsewhere\n")
    assert demo.ensure_model(tmp_path, "nuskin", 50, log=log) == 0
    assert len(calls) == 2
    assert "retraining" in log.getvalue()


def test_fingerprint_follows_scene_and_settings():
    base = demo.training_fingerprint("nuskin", "tap_rod30_nuskin", 300)
    assert base == demo.training_fingerprint("nuskin", "tap_rod30_nuskin", 300)
    assert base != demo.training_fingerprint("nuskin", "tap_rod20_nuskin", 300)
    assert base != demo.training_fingerprint("nuskin", "tap_rod30_nuskin", 100)
