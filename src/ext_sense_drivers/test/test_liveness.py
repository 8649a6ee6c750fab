"""The drivers' stall check: silence while streaming is WARN, then ERROR, and clears on data."""

import pytest

from ext_sense_drivers.liveness import DriverLiveness, StreamWatch
from ext_sense_runtime.diagnostics import Level
from ext_sense_runtime.stamps import MS


class FakeClock:
    def __init__(self) -> None:
        self.now = 1_000 * MS

    def __call__(self) -> int:
        return self.now


def _watch(clock, rate=540.0, name="receiver words on /dev/x"):
    return StreamWatch(name, rate, 200 * MS, 500 * MS, clock=clock)


def test_silence_while_streaming_warns_then_errors_naming_the_stream_and_clears():
    clock = FakeClock()
    watch = _watch(clock)
    live = DriverLiveness([watch])
    live.set_streaming(True)
    watch.on_data(10)
    for _ in range(4):  # an idle stream: data every 50 ms
        clock.now += 50 * MS
        watch.on_data(27)
        live.set_streaming(True)
    assert live.level() == Level.OK
    assert not live.changed()
    assert live.check()[1] == "streaming"

    clock.now += 150 * MS
    live.set_streaming(True)
    assert live.level() == Level.OK
    clock.now += 60 * MS  # 210 ms silent
    live.set_streaming(True)
    level, message, values = live.check()
    assert level == Level.WARN
    assert live.changed()
    assert "no receiver words on /dev/x for 210 ms" in message
    clock.now += 300 * MS  # 510 ms silent
    live.set_streaming(True)
    level, message, _ = live.check()
    assert level == Level.ERROR
    assert live.changed()
    assert "receiver words on /dev/x" in message

    watch.on_data(5)
    live.set_streaming(True)
    level, message, values = live.check()
    assert (level, message) == (Level.OK, "streaming")
    assert live.changed()
    assert values["stream_stalls"] == 1
    assert values["stream_longest_stall_ms"] == "510"


def test_silence_is_not_a_stall_while_not_streaming_or_right_after_it_starts():
    clock = FakeClock()
    watch = _watch(clock)
    live = DriverLiveness([watch])
    watch.on_data(3)
    clock.now += 5_000 * MS  # link down or node inactive: the link status reports it
    live.set_streaming(False)
    assert live.level() == Level.OK
    assert live.check()[1] == "not streaming"
    live.set_streaming(True)  # reconnected now: silence counts from here
    clock.now += 150 * MS
    live.set_streaming(True)
    assert live.level() == Level.OK
    clock.now += 100 * MS
    live.set_streaming(True)
    assert live.level() == Level.WARN
    live.set_streaming(False)  # the link dropped during the stall
    assert live.level() == Level.OK


def test_each_silent_sensor_is_named_and_a_rate_of_zero_is_not_checked():
    clock = FakeClock()
    a, b = _watch(clock, 100.0, "frames of sensor 0"), _watch(clock, 100.0, "frames of sensor 2")
    live = DriverLiveness([a, b])
    live.set_streaming(True)
    clock.now += 300 * MS
    a.on_data(1)
    live.set_streaming(True)
    level, message, _ = live.check()
    assert level == Level.WARN
    assert "frames of sensor 2" in message
    assert "sensor 0" not in message

    off = DriverLiveness([_watch(clock, 0.0)])
    off.set_streaming(True)
    clock.now += 10_000 * MS
    off.set_streaming(True)
    assert off.check()[:2] == (Level.OK, "not checked: the source is silent when idle")


def test_a_slow_stream_never_stalls_inside_three_of_its_intervals():
    clock = FakeClock()
    watch = _watch(clock, rate=2.0)  # 500 ms between items
    assert watch.warn_ns == 1_500 * MS
    assert watch.error_ns == 1_500 * MS
    live = DriverLiveness([watch])
    live.set_streaming(True)
    clock.now += 1_000 * MS
    live.set_streaming(True)
    assert live.level() == Level.OK


@pytest.mark.parametrize(
    ("rate", "warn", "error", "match"),
    [
        (-1.0, 200, 500, "expected_rate_hz"),
        (float("nan"), 200, 500, "expected_rate_hz"),
        (540.0, 500, 200, "warn <= error"),
        (540.0, 0, 200, "warn <= error"),
    ],
)
def test_bad_settings_are_refused(rate, warn, error, match):
    with pytest.raises(ValueError, match=match):
        StreamWatch("s", rate, warn * MS, error * MS)
