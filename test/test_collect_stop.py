"""``ext-sense collect`` stopped by a signal to it alone while the operator is asked: the session
is saved (resumable), its bag closed, its graph stopped with no node left running, and the exit
status says which signal (128 + N). collect spins its recorder through the same helper as every
rclpy entry point (``RosSession``), its first stop signal interrupting the operator's prompt.
"""

from __future__ import annotations

import os
import signal
import subprocess
import threading
import time

import pytest
from sim_models import EXE, train_sim_model

from ext_sense_bags import BagReader

pytestmark = [pytest.mark.slow, pytest.mark.ros, pytest.mark.timeout(240)]


@pytest.mark.parametrize("signum", [signal.SIGHUP, signal.SIGTERM], ids=lambda s: s.name)
def test_a_stop_signal_saves_the_session_and_leaves_no_node(signum, tmp_path):
    model, _ = train_sim_model(tmp_path, "tap_rod30_nuskin", "tap_localization", 16)
    bag = tmp_path / "session"
    proc = subprocess.Popen(
        [*EXE, "collect", "tap_localization", str(bag), "--trials", "5", f"model:={model}"],
        stdin=subprocess.PIPE,  # an operator who never answers
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        start_new_session=True,
    )
    out: list[str] = []
    reader = threading.Thread(target=lambda: out.extend(proc.stdout), daemon=True)
    reader.start()
    try:
        end = time.monotonic() + 120
        while not any("  contact: label" in line for line in out) and time.monotonic() < end:
            assert proc.poll() is None, "".join(out) + proc.stderr.read()
            time.sleep(0.1)
        time.sleep(0.5)  # the first tap recorded and shown, the operator asked about it
        os.kill(proc.pid, signum)  # collect alone, not its group
        rc = proc.wait(timeout=30)
        reader.join(timeout=5)
        err = proc.stderr.read()
        group_gone = _group_gone(proc.pid)
    finally:
        if not _group_gone(proc.pid):
            os.killpg(proc.pid, signal.SIGKILL)
        proc.wait(timeout=10)
    text = "".join(out)
    assert rc == 128 + signum, text[-2000:] + err[-3000:]
    assert group_gone, "a node of the graph outlived collect"
    assert "unfinished: continue with --resume" in text, text[-2000:]
    assert (bag / "collect.json").is_file()
    with BagReader(bag) as reader_:  # closed: complete, with its metadata
        assert reader_.topics["/extsense/nuskin/packets"].count > 0
    assert "Traceback" not in err, err[-3000:]


def _group_gone(pgid: int) -> bool:
    try:
        os.killpg(pgid, 0)
    except ProcessLookupError:
        return True
    return False
