"""Test-wide settings: isolate ROS 2 traffic and logs of this test run.

Each pytest run gets its own ROS_DOMAIN_ID (from the process id; under pytest-xdist one per
worker) and localhost-only discovery, so parallel runs on one machine never see each other's
topics; logs go under build/.
Shared-memory segments that crashed participants leave in /dev/shm are cleaned at the end.
A test that outlives its timeout by a grace period (hung in C, or in a teardown after the
timeout fired) ends its process with every thread's stack on stderr, instead of hanging CI.
"""

from __future__ import annotations

import contextlib
import faulthandler
import os
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from ext_sense.cli import hear_interrupts

ROOT = Path(__file__).resolve().parent
SHARED_DATA = ROOT.parent / "shared" / "data"

# A shell without job control starts a background `make test` with SIGINT ignored, and every
# process the tests start would inherit that: a test's Ctrl-C to a graph it started (its
# runner's first tenth of a second, test_shutdown.py) was lost. The tests send the signals a
# terminal would, so they run with the terminal's disposition.
hear_interrupts()

os.environ.setdefault("ROS_DOMAIN_ID", str(1 + os.getpid() % 200))
if worker := os.environ.get("PYTEST_XDIST_WORKER"):  # gw0, gw1, ...: a domain each (below 233)
    domain = int(os.environ["ROS_DOMAIN_ID"]) + 1 + int(worker[2:])
    os.environ["ROS_DOMAIN_ID"] = str(domain % 232)
os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
os.environ.setdefault("ROS_LOG_DIR", str(ROOT / "build" / "ros_log"))
os.environ.setdefault("RCUTILS_LOGGING_BUFFERED_STREAM", "1")


@pytest.fixture(scope="session")
def shared_data() -> Path:
    """``../shared/data``; tests that need it skip with a clear message when it is absent."""
    if not SHARED_DATA.is_dir():
        pytest.skip(
            f"real captures not available: {SHARED_DATA} is absent (it lives beside the repo)"
        )
    return SHARED_DATA


@pytest.fixture(scope="session")
def food_poking_dir(shared_data: Path) -> Path:
    """The real NUSkin food-poking captures."""
    path = shared_data / "nuskin_food_poking"
    if not path.is_dir():
        pytest.skip(f"real captures not available: {path} is absent")
    return path


FOOD_SESSIONS = (
    "nuskin_food_poking",
    "nuskin_food_poking_2021-04-03",
    "nuskin_food_poking_2021-04-05",
)


@pytest.fixture(scope="session")
def food_sessions(shared_data: Path) -> list[Path]:
    """The three real NUSkin food-poking sessions (1, 3 and 5 April 2021), one folder each."""
    paths = [shared_data / name for name in FOOD_SESSIONS]
    absent = [str(p) for p in paths if not p.is_dir()]
    if absent:
        pytest.skip(f"real food sessions not available: {', '.join(absent)} absent")
    return paths


# pytest-timeout's signal method raises in the main thread, so it cannot stop a test blocked in
# C (a DDS call, a native thread pool) or one whose teardown hangs after the timeout has fired:
# either held a pytest-xdist worker, and with it `make test`, until CI's own limit. This watchdog,
# faulthandler's C thread, dumps every thread's stack and ends the process: the worker is reported
# as crashed on the test that hung (and replaced), or the serial lane fails there. It is armed per
# phase (setup, call, teardown), since pytest cancels faulthandler's timer when a phase fails.
HANG_GRACE_S = float(os.environ.get("EXT_SENSE_HANG_GRACE_S", "60"))
"""Beyond a test's timeout, per phase; the environment variable shortens it for its own test."""
_STDERR_FD: list[int] = []


def pytest_configure(config: pytest.Config) -> None:
    """Keep a copy of the real stderr (output capture replaces fd 2 while tests run)."""
    _STDERR_FD.append(os.dup(2))


_TIMEOUT_S = pytest.StashKey[float]()


@pytest.hookimpl(tryfirst=True)
def pytest_timeout_set_timer(item: pytest.Item, settings: Any) -> None:
    """Keep pytest-timeout's limit for the watchdog (then pytest-timeout sets its own timer).

    The limit it settled on: the marker, ``--timeout``, ``PYTEST_TIMEOUT`` or the ini file.
    """
    item.stash[_TIMEOUT_S] = settings.timeout


@contextlib.contextmanager
def _hang_watchdog(item: pytest.Item) -> Iterator[None]:
    timeout = item.stash.get(_TIMEOUT_S, None)
    if not timeout or not _STDERR_FD:
        yield
        return
    faulthandler.dump_traceback_later(timeout + HANG_GRACE_S, exit=True, file=_STDERR_FD[0])
    try:
        yield
    finally:
        faulthandler.cancel_dump_traceback_later()


@pytest.hookimpl(wrapper=True, trylast=True)  # inside pytest-timeout's: its limit is set
def pytest_runtest_setup(item: pytest.Item) -> Iterator[None]:
    """The setup phase, under the hang watchdog."""
    with _hang_watchdog(item):
        return (yield)


@pytest.hookimpl(wrapper=True, trylast=True)  # inside pytest-timeout's: its limit is set
def pytest_runtest_call(item: pytest.Item) -> Iterator[None]:
    """The call phase, under the hang watchdog."""
    with _hang_watchdog(item):
        return (yield)


@pytest.hookimpl(wrapper=True, trylast=True)  # inside pytest-timeout's: its limit is set
def pytest_runtest_teardown(item: pytest.Item, nextitem: pytest.Item | None) -> Iterator[None]:
    """The teardown phase, under the hang watchdog."""
    with _hang_watchdog(item):
        return (yield)


SHM = Path("/dev/shm")
_SHM_AT_START: set[str] = set()


def _fastdds_files() -> set[str]:
    try:
        return {p.name for p in SHM.iterdir() if p.name.startswith(("fastdds_", "fastrtps_"))}
    except OSError:
        return set()


def _files_in_use() -> set[str]:
    """Names under /dev/shm that a live process has open or mapped."""
    used: set[str] = set()
    for proc in Path("/proc").iterdir():
        if not proc.name.isdigit():
            continue
        try:
            for line in (proc / "maps").read_text().splitlines():
                if "/dev/shm/" in line:
                    used.add(line.rsplit("/", 1)[-1])
            for fd in (proc / "fd").iterdir():
                target = os.readlink(fd)
                if target.startswith("/dev/shm/"):
                    used.add(target.rsplit("/", 1)[-1])
        except OSError:
            continue
    return used


def pytest_sessionstart(session: pytest.Session) -> None:
    """Remember the Fast DDS shared-memory files that existed before this run."""
    _SHM_AT_START.update(_fastdds_files())


def pytest_sessionfinish(session: pytest.Session, exitstatus: int) -> None:
    """Remove the Fast DDS shared-memory files this run created and nothing uses any more.

    Processes killed hard (as fault tests do) leave their segments and port locks behind.
    """
    leftover = _fastdds_files() - _SHM_AT_START
    if not leftover:
        return
    in_use = _files_in_use()
    for name in leftover - in_use:
        try:
            (SHM / name).unlink()
        except OSError:
            continue
