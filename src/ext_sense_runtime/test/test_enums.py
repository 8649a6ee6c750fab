"""The shared task and sensor names."""

from __future__ import annotations

import pytest

from ext_sense_runtime.enums import Sensor, Task


class _PackageError(Exception):
    pass


@pytest.mark.parametrize("task", list(Task))
def test_task_round_trips_through_label_name_and_value(task):
    assert Task.parse(task.label) is task
    assert Task.parse(task.name) is task
    assert Task.parse(int(task)) is task
    assert Task.parse(task) is task


@pytest.mark.parametrize("sensor", list(Sensor))
def test_sensor_round_trips_through_label_name_and_value(sensor):
    assert Sensor.parse(sensor.label) is sensor
    assert Sensor.parse(f" {sensor.name} ") is sensor
    assert Sensor.parse(int(sensor)) is sensor


def test_aliases_and_regression():
    assert Task.parse("tap") is Task.TAP_LOCALIZATION
    assert Task.parse("food-identification") is Task.FOOD_IDENTIFICATION
    assert [t.is_regression for t in Task] == [True, False, False]


def test_bad_names_raise_the_callers_error_naming_the_parameter():
    with pytest.raises(ValueError, match="The 'task' parameter must be one of 'tap_localization'"):
        Task.parse("poke")
    with pytest.raises(_PackageError, match=r"The 'task' parameter .* Got 7 instead"):
        Task.parse(7, _PackageError)
    with pytest.raises(
        _PackageError, match="The 'sensor' parameter must be one of 'nuskin', 'biotac'"
    ):
        Sensor.parse("gelsight", _PackageError)


def test_no_rclpy_needed():
    import subprocess
    import sys

    code = "import sys, ext_sense_runtime.enums; print('rclpy' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"
