"""The window node's parameters give the profile's windows and the input's liveness (no ROS)."""

from __future__ import annotations

import pytest

from ext_sense_perception.nodes.window_parameters import (
    WindowParameters,
    input_liveness,
    window_config,
)
from ext_sense_perception.online.window import WindowConfig
from ext_sense_runtime.parameters import build
from ext_sense_runtime.stamps import MS


class _Log:
    def __init__(self) -> None:
        self.lines: list[str] = []

    def info(self, message: str) -> None:
        self.lines.append(message)

    def warning(self, message: str) -> None:
        self.lines.append(message)


def test_without_a_card_the_task_profile_cuts_the_windows():
    log = _Log()
    p = WindowParameters(task="tap", model_path="/nonexistent/model")
    config, sensor_ids, source = window_config(p, log)
    expected = WindowConfig.for_task("tap_localization", "nuskin")
    assert (config.pre_ns, config.post_ns, config.anytime_post_ns) == (
        expected.pre_ns,
        expected.post_ns,
        expected.anytime_post_ns,
    )
    assert (sensor_ids, source) == ((0,), "task")
    assert "task profile of tap" in log.lines[0]


def test_the_stuck_taxel_settings_and_the_slots_are_the_parameters():
    p = build(
        WindowParameters,
        {
            "sensor": "biotac",
            "model_path": "/nonexistent/model",
            "stuck_after_ms": 250.0,
            "sensor_ids": [1, 0],
        },
    )
    config, sensor_ids, _ = window_config(p, _Log())
    assert config.stuck_after_ns == 250 * MS
    assert sensor_ids == (1, 0)


def test_the_expected_rate_is_the_sensors_unless_given():
    p = WindowParameters(model_path="/nonexistent/model")
    config, _, _ = window_config(p, _Log())
    assert input_liveness(p, config, "packets").expected_rate_hz == 1000.0
    biotac = WindowParameters(sensor="biotac", model_path="/nonexistent/model")
    config, _, _ = window_config(biotac, _Log())
    assert input_liveness(biotac, config, "packets").expected_rate_hz == 100.0
    given = WindowParameters(
        sensor="biotac", model_path="/nonexistent/model", expected_rate_hz=50.0
    )
    assert input_liveness(given, config, "packets").expected_rate_hz == 50.0


def test_a_bad_task_is_one_line_naming_it():
    with pytest.raises(ValueError, match=r"contact_window: .*task"):
        window_config(WindowParameters(task="juggling"), _Log())
