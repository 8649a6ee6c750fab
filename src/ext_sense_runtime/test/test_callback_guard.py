from __future__ import annotations

import asyncio

import pytest

from ext_sense_runtime.callback_guard import CallbackGuard, describe
from ext_sense_runtime.diagnostics import Level, Updater


class FakeClock:
    def __init__(self) -> None:
        self.ns = 0

    def __call__(self) -> int:
        return self.ns


def _guard() -> tuple[CallbackGuard, list[str], FakeClock]:
    logged: list[str] = []
    clock = FakeClock()
    return CallbackGuard(logged.append, clock=clock, recent_ns=10_000_000_000), logged, clock


def test_an_exception_is_caught_counted_and_logged_once_with_its_cause():
    guard, logged, _ = _guard()
    calls = []

    @guard
    def on_msg(x: int) -> None:
        calls.append(x)
        if x < 0:
            raise ValueError(f"negative {x}")

    on_msg(-1)
    on_msg(-2)
    on_msg(3)
    assert calls == [-1, -2, 3]  # the callback goes on being called
    assert guard.counts["on_msg"] == 2
    assert guard.total == 2
    assert len(logged) == 1
    assert "on_msg: ValueError: negative -1" in logged[0]
    assert "test_callback_guard.py" in logged[0]
    assert guard.last_cause.startswith("on_msg: ValueError: negative -2")


def test_a_new_exception_type_is_logged_again():
    guard, logged, _ = _guard()
    errors = iter([ValueError("a"), KeyError("b"), ValueError("c")])

    def tick() -> None:
        raise next(errors)

    guarded = guard.wrap(tick, name="timer")
    for _ in range(3):
        guarded()
    assert [m.split(":")[1].strip() for m in logged] == ["ValueError", "KeyError"]
    assert guard.counts == {"timer": 3}


def test_return_values_pass_and_stops_are_not_swallowed():
    guard, _, _ = _guard()
    assert guard(lambda: 7)() == 7

    def interrupted() -> None:
        raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        guard(interrupted)()
    assert guard.total == 0


def test_a_fallback_gives_the_return_value_after_an_exception():
    guard, _, _ = _guard()

    def on_set(params: list[int]) -> str:
        raise TypeError("not a list of ints")

    wrapped = guard.wrap(on_set, fallback=lambda err: f"refused: {err}")
    assert wrapped([1]) == "refused: not a list of ints"
    assert guard.counts["on_set"] == 1


def test_coroutine_callbacks_are_guarded():
    guard, logged, _ = _guard()

    async def service(req: int) -> int:
        if req == 0:
            raise ZeroDivisionError("zero")
        return 10 // req

    wrapped = guard(service)
    assert asyncio.run(wrapped(2)) == 5
    assert asyncio.run(wrapped(0)) is None
    assert guard.counts["service"] == 1
    assert len(logged) == 1


def test_status_is_ok_then_error_while_recent_then_warn():
    guard, _, clock = _guard()
    updater = Updater("node", clock=clock)
    guard.attach(updater)
    (report,) = updater.update(force=True)
    assert (report.name, report.level) == ("callbacks", Level.OK)
    clock.ns = 5_000_000_000
    guard.wrap(lambda: 1 / 0, name="divide")()
    (report,) = updater.update(force=True)
    assert report.level == Level.ERROR
    assert "divide: ZeroDivisionError" in report.message
    assert ("exceptions_divide", "1") in report.values
    clock.ns += 10_000_000_001
    (report,) = updater.update(force=True)
    assert report.level == Level.WARN
    assert ("exceptions_total", "1") in report.values


def test_describe_names_type_message_and_place():
    try:
        {}["missing"]
    except KeyError as err:
        text = describe(err)
    assert text.startswith("KeyError: 'missing' (at test_callback_guard.py:")
    assert describe(RuntimeError()) == "RuntimeError"
