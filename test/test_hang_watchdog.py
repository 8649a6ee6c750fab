"""The test-wide hang watchdog (conftest.py): a test that outlives its timeout ends its process.

pytest-timeout's signal cannot stop a teardown that hangs after the timeout has failed the
test (nor a call blocked in C); without the watchdog such a test held `make test` until CI's
own limit. Here a scratch test does that in a pytest of its own, with the root conftest
loaded as a plugin and a one-second grace.
"""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

HANGING_TEARDOWN = """
    import time

    import pytest


    @pytest.fixture
    def sticky():
        yield
        time.sleep(600)  # a teardown that never ends once the timeout has fired


    @pytest.mark.timeout(1)
    def test_outlives_its_timeout(sticky):
        time.sleep(600)
"""


def _run_pytest(test_file: Path, *args: str) -> tuple[subprocess.CompletedProcess, float]:
    env = {**os.environ, "EXT_SENSE_HANG_GRACE_S": "1", "PYTHONPATH": str(ROOT)}
    env.pop("PYTEST_XDIST_WORKER", None)
    start = time.monotonic()
    done = subprocess.run(
        [sys.executable, "-m", "pytest", "-p", "conftest", "-p", "no:cacheprovider", *args],
        cwd=test_file.parent,
        env=env,
        capture_output=True,
        text=True,
        timeout=60,
    )
    return done, time.monotonic() - start


def test_a_teardown_hanging_after_the_timeout_ends_the_run_with_its_stack(tmp_path):
    test_file = tmp_path / "test_scratch_hang.py"
    test_file.write_text(textwrap.dedent(HANGING_TEARDOWN))
    done, took_s = _run_pytest(test_file, str(test_file))
    assert done.returncode != 0, done.stdout[-2000:]
    assert took_s < 30, took_s  # timeout 1 s, then the teardown's 1 + 1 s; not the 600 s sleep
    assert "Timeout (0:00:02)!" in done.stderr, done.stderr[-2000:]
    assert "in sticky" in done.stderr, done.stderr[-2000:]  # the hanging frame is named


def test_the_limit_is_the_one_pytest_timeout_settled_on_here_from_the_command_line(tmp_path):
    """No marker and no ini file: ``--timeout`` alone sets the limit the watchdog adds to."""
    test_file = tmp_path / "test_scratch_hang.py"
    test_file.write_text(textwrap.dedent(HANGING_TEARDOWN).replace("@pytest.mark.timeout(1)\n", ""))
    done, took_s = _run_pytest(test_file, "--timeout", "1", str(test_file))
    assert done.returncode != 0, done.stdout[-2000:]
    assert took_s < 30, took_s
    assert "Timeout (0:00:02)!" in done.stderr, done.stderr[-2000:]


def test_an_xdist_worker_that_hangs_is_reported_crashed_and_the_run_goes_on(tmp_path):
    test_file = tmp_path / "test_scratch_hang.py"
    test_file.write_text(
        textwrap.dedent(HANGING_TEARDOWN) + "\n\ndef test_after():\n    assert True\n"
    )
    done, took_s = _run_pytest(test_file, "-n", "2", str(test_file))
    assert done.returncode == 1, done.stdout[-2000:]
    assert took_s < 40, took_s
    assert "crashed while running" in done.stdout, done.stdout[-2000:]
    assert "test_outlives_its_timeout" in done.stdout
    assert "1 passed" in done.stdout, done.stdout[-2000:]
