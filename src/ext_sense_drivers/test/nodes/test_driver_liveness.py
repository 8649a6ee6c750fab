"""A real stall: the device process is stopped (SIGSTOP) while the driver reads its pty.

A separate process plays the device as the real ones behave while powered: a NUSkin receiver
sending its idle stream (540 words/s), a BioTac bridge sending each sensor's frames at 100 Hz.
Stopping it leaves the pty open and silent, which the link status cannot see; the driver's
``liveness`` status must turn WARN, then ERROR, within 1 s of the stop, name the silent stream,
and return to OK once the process continues.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

pytestmark = pytest.mark.ros

rclpy = pytest.importorskip("rclpy")

from diagnostic_msgs.msg import DiagnosticArray  # noqa: E402
from rclpy.executors import SingleThreadedExecutor  # noqa: E402
from rclpy.parameter import Parameter  # noqa: E402

from ext_sense_runtime.qos import DIAGNOSTICS_QOS  # noqa: E402

DEVICE = r"""
import os, sys, time, tty
import numpy as np
kind, link = sys.argv[1], sys.argv[2]
master, slave = os.openpty()
tty.setraw(slave)
os.symlink(os.ttyname(slave), link)
print("ready", flush=True)
rng = np.random.default_rng(0)
seq = 0
next_t = time.monotonic()
while True:
    if kind == "nuskin":  # the receiver's idle stream: 540 words/s, sent every 10 ms
        from ext_sense_drivers.nuskin.wire import encode_words
        data = encode_words(rng.integers(1, 81, 5), rng.integers(0, 1024, 5))
    else:  # the bridge: a frame of sensors 0 and 3 every 10 ms
        from ext_sense_drivers.biotac.encoder import encode_frame
        from ext_sense_drivers.biotac.words import encode_values
        values = encode_values(np.full(44, 2000))
        data = b"".join(encode_frame(seq, s, values) for s in (0, 3))
        seq = (seq + 1) % 65536
    os.write(master, data)
    next_t += 0.01
    time.sleep(max(0.0, next_t - time.monotonic()))
"""


def _liveness(arr: DiagnosticArray):
    for status in arr.status:
        if status.name.endswith(": liveness"):
            return status
    return None


@pytest.mark.parametrize(
    ("kind", "stream"),
    [("nuskin", "receiver words on"), ("biotac", "frames of BioTac sensor")],
)
def test_sigstop_of_the_device_warns_then_errors_within_1_s_and_clears(tmp_path, kind, stream):
    link = tmp_path / f"{kind}.pty"
    device = subprocess.Popen(
        [sys.executable, "-c", DEVICE, kind, str(link)], stdout=subprocess.PIPE, text=True
    )
    context = rclpy.Context()
    rclpy.init(context=context)
    driver = probe = None
    try:
        assert device.stdout.readline().strip() == "ready"
        if kind == "nuskin":
            from ext_sense_drivers.nodes.nuskin_driver import NuskinDriverNode as Driver

            extra = []
        else:
            from ext_sense_drivers.nodes.biotac_driver import BioTacDriverNode as Driver

            extra = [Parameter("expected_sensors", value=[0, 3])]
        driver = Driver(
            context=context, parameter_overrides=[Parameter("port", value=str(link)), *extra]
        )
        probe = rclpy.create_node("probe", context=context)
        got: list[tuple[float, object]] = []

        def on_diag(arr: DiagnosticArray) -> None:
            status = _liveness(arr)
            if status is not None:
                got.append((time.monotonic(), status))

        probe.create_subscription(DiagnosticArray, "/diagnostics", on_diag, DIAGNOSTICS_QOS)
        if extra:  # BioTac: both sensors must be watched
            assert sorted(driver._watches) == [0, 3]
        executor = SingleThreadedExecutor(context=context)
        executor.add_node(driver)
        executor.add_node(probe)

        def spin_until(predicate, timeout_s):
            end = time.monotonic() + timeout_s
            while time.monotonic() < end:
                executor.spin_once(timeout_sec=0.01)
                if predicate():
                    return True
            return False

        def streaming_ok():
            return any(s.message == "streaming" and s.level == b"\x00" for _, s in got)

        assert spin_until(streaming_ok, 10.0), [s.message for _, s in got]
        spin_until(lambda: False, 0.5)  # a healthy stream stays OK
        assert all(s.level == b"\x00" for _, s in got), [s.message for _, s in got]

        os.kill(device.pid, signal.SIGSTOP)
        stopped = time.monotonic()
        got.clear()
        assert spin_until(lambda: any(s.level == b"\x02" for _, s in got), 3.0), [
            s.message for _, s in got
        ]
        levels = [(t - stopped, s.level[0], s.message) for t, s in got]
        warn = next(x for x in levels if x[1] == 1)
        error = next(x for x in levels if x[1] == 2)
        assert warn[0] < error[0] < 1.0, levels
        for _, _, message in (warn, error):
            assert message.startswith("stall: no "), message
            assert stream in message, message
            assert str(link) in message, message
        if kind == "biotac":  # both sensors fell silent: both are named
            assert "sensor 0" in error[2], error
            assert "sensor 3" in error[2], error

        os.kill(device.pid, signal.SIGCONT)
        resumed = time.monotonic()
        got.clear()
        assert spin_until(lambda: any(s.level == b"\x00" for _, s in got), 3.0)
        back = next(t for t, s in got if s.level == b"\x00")
        print(f"{kind}: after SIGSTOP {levels[:3]}; OK {back - resumed:.3f} s after SIGCONT")
        assert back - resumed < 1.0
        assert got[-1][1].message == "streaming"
        values = {kv.key: kv.value for kv in got[-1][1].values}
        assert int(values.get("stream_stalls", values.get("stream_0_stalls", 0))) == 1
    finally:
        device.send_signal(signal.SIGCONT)
        device.kill()
        device.wait()
        for node in (driver, probe):
            if node is not None:
                node.destroy_node()
        rclpy.try_shutdown(context=context)
        Path(link).unlink(missing_ok=True)
