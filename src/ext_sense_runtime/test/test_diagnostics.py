from __future__ import annotations

import pytest

from ext_sense_runtime.diagnostics import Level, RateTask, Updater


class FakeClock:
    def __init__(self) -> None:
        self.ns = 0

    def __call__(self) -> int:
        return self.ns


def test_updater_reports_only_when_due():
    clock = FakeClock()
    updater = Updater("port0", period_ns=1_000_000_000, clock=clock)
    updater.add_check("link", lambda: (Level.OK, "open", {"bytes_total": 3}))
    first = updater.update()
    assert [(r.name, r.level, r.hardware_id) for r in first] == [("link", Level.OK, "port0")]
    assert first[0].values == (("bytes_total", "3"),)
    clock.ns += 500_000_000
    assert updater.update() == []
    clock.ns += 500_000_000
    assert len(updater.update()) == 1


def test_a_failing_check_is_reported_not_raised():
    updater = Updater("x", clock=FakeClock())

    def broken():
        raise RuntimeError("sensor gone")

    updater.add_check("broken", broken)
    (report,) = updater.update(force=True)
    assert report.level == Level.ERROR
    assert "sensor gone" in report.message


@pytest.mark.parametrize(
    ("events_per_s", "level", "message"),
    [
        (100, Level.OK, "rate ok"),
        (50, Level.WARN, "rate too low"),
        (200, Level.WARN, "rate too high"),
        (0, Level.ERROR, "no events"),
    ],
)
def test_rate_task_levels(events_per_s, level, message):
    clock = FakeClock()
    task = RateTask("frames", min_hz=90.0, max_hz=110.0, tolerance=0.05, clock=clock)
    assert task.report("id").message == "warming up"
    for _ in range(3):
        clock.ns += 1_000_000_000
        task.add(events_per_s)
        report = task.report("id")
    assert report.level == level
    assert report.message == message
    assert dict(report.values)["rate_per_s"] == f"{float(events_per_s):.1f}"


def test_rate_window_slides():
    clock = FakeClock()
    task = RateTask("r", min_hz=0.0, max_hz=1e9, window=2, clock=clock)
    task.report("")
    for n in (10, 10, 1000, 1000):
        clock.ns += 1_000_000_000
        task.add(n)
        task.report("")
    assert task.rate() == pytest.approx(1000.0)
