"""The Robotiq client on its own: opening a port that is not there."""

from __future__ import annotations

import pytest

from ext_sense_drivers.robotiq import FaultKind, RobotiqClient, RobotiqError


def test_missing_port_is_a_serial_error(tmp_path):
    with pytest.raises(RobotiqError, match="Cannot open serial port") as info:
        RobotiqClient.open(str(tmp_path / "ttyUSB_absent"))
    assert info.value.kind == FaultKind.SERIAL
