"""Trials simulated ahead in a low-priority child process: the same trials, ended cleanly."""

from __future__ import annotations

import contextlib
import dataclasses
import os
import pickle
import signal
import subprocess
import sys
import threading
import time

import pytest

from ext_sense_sim.errors import SceneError
from ext_sense_sim.scene import load_scene
from ext_sense_sim.streaming import stream
from ext_sense_sim.trial_plan import plan_trials
from ext_sense_sim.trials_ahead import WORLD_NICE, TrialsAhead


def test_the_child_gives_the_trials_the_device_would_simulate_itself_in_the_same_order():
    scene = load_scene("tap_rod30_nuskin")
    here = plan_trials(scene, 7)
    with TrialsAhead(scene, 7) as ahead:
        for _ in range(3):
            a, b = next(ahead), next(here)
            assert a.trial == b.trial
            assert a.chunks == b.chunks
            assert (a.onset_ns, a.tap_position_m, a.class_label) == (
                b.onset_ns,
                b.tap_position_m,
                b.class_label,
            )
        mine = os.getpriority(os.PRIO_PROCESS, 0)
        assert os.getpriority(os.PRIO_PROCESS, ahead.pid) == min(19, mine + WORLD_NICE)
    assert not ahead.alive()  # ended on exit


def test_a_stop_ends_a_wait_for_the_next_trial_and_an_error_in_the_child_is_named():
    scene = load_scene("tap_rod30_nuskin")
    stop = threading.Event()
    with TrialsAhead(scene, 1, stop) as ahead:
        stop.set()
        t0 = time.monotonic()
        assert next(ahead, None) is None
        assert time.monotonic() - t0 < 1.0
    broken = dataclasses.replace(scene, effects=())  # no wire effect: the child's error
    with TrialsAhead(broken, 1) as ahead, pytest.raises(SceneError, match="trial simulator"):
        next(ahead)


def test_a_stream_of_trials_simulated_ahead_writes_the_same_bytes():
    """``stream(ahead=True)`` on a fake clock writes what the in-process stream writes."""
    scene = load_scene("tap_rod30_nuskin")

    def run(ahead: bool) -> list[bytes]:
        now = [0]
        out: list[bytes] = []

        def sleep(s: float) -> None:
            now[0] += max(int(s * 1e9), 100_000)

        stream(
            scene,
            out.append,
            seed=3,
            trials=2,
            clock=lambda: now[0],
            sleep=sleep,
            ahead=ahead,
        )
        return out

    assert b"".join(run(True)) == b"".join(run(False))


def test_a_killed_device_leaves_no_simulator_behind():
    code = (
        "import sys, time\n"
        "from ext_sense_sim.scene import load_scene\n"
        "from ext_sense_sim.trials_ahead import TrialsAhead\n"
        "ahead = TrialsAhead(load_scene('tap_rod30_nuskin'), 1)\n"
        "next(ahead)\n"
        "print(ahead.pid, flush=True)\n"
        "time.sleep(60)\n"
    )
    device = subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE, text=True)
    try:
        child = int(device.stdout.readline())
        os.kill(device.pid, signal.SIGKILL)
        device.wait(timeout=10)
        deadline = time.monotonic() + 10.0
        while time.monotonic() < deadline and _alive(child):
            time.sleep(0.1)
        assert not _alive(child), "the simulator outlived its device"
    finally:
        device.kill()


def _alive(pid: int) -> bool:
    try:
        with open(f"/proc/{pid}/stat") as fh:
            return fh.read().split(") ")[1][0] != "Z"  # a zombie has ended
    except FileNotFoundError:
        return False


def test_the_child_keeps_trials_simulated_ahead_while_the_device_does_not_read(monkeypatch):
    """Up to ``ahead`` trials wait ready, in order; a closed pipe ends the simulation."""
    from ext_sense_sim import trials_ahead
    from ext_sense_sim.trial_plan import PlannedTrial

    made: list[int] = []

    def plans(scene, seed):  # trials too big for the pipe to hold one
        k = 0
        while True:
            made.append(k)
            yield PlannedTrial(k, [(0, bytes(200_000))], 0, 0.0, "stable")
            k += 1

    monkeypatch.setattr(trials_ahead, "plan_trials", plans)
    r, w = os.pipe()
    out = os.fdopen(w, "wb")
    child = threading.Thread(target=trials_ahead.simulate, args=(None, 0, out, 5))
    child.start()
    deadline = time.monotonic() + 5.0
    while time.monotonic() < deadline and len(made) < 7:
        time.sleep(0.01)
    time.sleep(0.2)
    # five waiting, one in the writer's hand, one in the simulator's (blocked on the queue)
    assert 5 <= len(made) <= 8
    with os.fdopen(r, "rb") as src:
        got = [pickle.load(src).trial for _ in range(10)]
    child.join(timeout=5.0)  # the read end closed: the writer's next write fails
    with contextlib.suppress(OSError):
        out.close()
    assert got == list(range(10))
    assert not child.is_alive()
