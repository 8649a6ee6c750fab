"""The tap graph on a serial device, as a user runs it on a real NUSkin: the monitor has no
ground truth to score against, so it prints each final estimate as it comes and ends the graph
after ``trials:=N`` of them, with a summary (before: no tap line, no summary, and the graph
never ended, the monitor's end counting ground-truth trials that a serial source has none of).

The device is the emulated NUSkin on a pty (``ext-sense sim serve nuskin``), a process of its
own that the graph knows only as ``source:=serial port:=PTY``.
"""

from __future__ import annotations

import os
import re
import signal
import time

import pytest
from sim_models import finish_graph, spawn, stop_problems, train_sim_model

pytestmark = [pytest.mark.ros, pytest.mark.slow, pytest.mark.timeout(400)]

TRIALS = 5
SUMMARY = re.compile(
    rf"^summary: estimates={TRIALS} degraded=(\d+) compute_p50_ms=[\d.]+ "
    r"compute_p99_ms=[\d.]+ \(no ground truth\)$"
)


def test_the_serial_graph_prints_each_estimate_and_ends_after_trials(tmp_path):
    model, _ = train_sim_model(tmp_path, "tap_rod30_nuskin", "tap_localization", 16)
    link = tmp_path / "nuskin.pty"
    device = spawn("sim", "serve", "nuskin", "--scene", "tap_rod30_nuskin", "--link", str(link))
    try:
        end = time.monotonic() + 60
        while not link.exists() and time.monotonic() < end and device.poll() is None:
            time.sleep(0.1)
        assert link.exists(), device.communicate(timeout=5)
        graph = spawn(
            "run", "tap_localization", "source:=serial", f"port:={link}", f"trials:={TRIALS}",
            f"model:={model}",
        )  # fmt: skip
        out, err = finish_graph(graph, 240, "the serial graph")
    finally:
        if device.poll() is None:
            os.killpg(device.pid, signal.SIGINT)
        device.communicate(timeout=20)
    lines = out.splitlines()
    taps = [line for line in lines if re.match(r"^tap +\d+: estimate +[\d.]+ cm", line)]
    assert len(taps) == TRIALS, out[-3000:]
    assert SUMMARY.match(lines[-1]), out[-3000:]
    assert not stop_problems(graph, out, err), err[-3000:]
