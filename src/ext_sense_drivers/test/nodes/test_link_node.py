"""The ``link`` diagnostics check the driver nodes share, from a reader in each state."""

from types import SimpleNamespace

import pytest

pytest.importorskip("rclpy")

from ext_sense_drivers.nodes.link_node import link_status
from ext_sense_drivers.transports import LinkState
from ext_sense_runtime.diagnostics import Level


def _reader(state, last_error=""):
    return SimpleNamespace(
        state=state,
        connects=2,
        disconnects=1,
        open_failures=3,
        bytes_total=960,
        dropped_bytes=0,
        last_error=last_error,
        scheduling=None,  # reader_priority 0: nothing asked
    )


@pytest.mark.parametrize(
    ("state", "level", "message"),
    [
        (LinkState.CONNECTED, Level.OK, "connected"),
        (LinkState.EXHAUSTED, Level.OK, "capture file replayed to its end"),
        (LinkState.BACKOFF, Level.ERROR, "link unavailable, retrying: gone"),
        (LinkState.CONNECTING, Level.WARN, "connecting"),
        (LinkState.STOPPED, Level.WARN, "stopped"),
    ],
)
def test_link_status_in_every_state(state, level, message):
    got_level, got_message, values = link_status(
        _reader(state, "gone"), "link", {"frames_published": 7, "qos_deadline_missed": 0}
    )
    assert (got_level, got_message) == (level, message)
    assert list(values) == [
        "port_state",
        "connects",
        "disconnects",
        "open_failures",
        "bytes_total",
        "dropped_bytes",
        "last_error",
        "reader_scheduling",
        "frames_published",
        "qos_deadline_missed",
    ]
    assert values["port_state"] == state.name.lower()
    assert values["frames_published"] == 7
    assert values["reader_scheduling"] == ""


def test_link_status_names_what_vanished():
    _, message, _ = link_status(_reader(LinkState.BACKOFF, "no such file"), "port", {})
    assert message == "port unavailable, retrying: no such file"
