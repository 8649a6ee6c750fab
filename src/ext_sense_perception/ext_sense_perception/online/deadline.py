"""When the window node must wake up with no input: the deadlines of a quiet stream (no ROS).

Windows close on data: a packet whose events (or, for an empty batch, whose stamp) pass a
window's end cuts that window in the subscription callback (:class:`~.stage.WindowStage`). Only a
stream that goes quiet needs a clock, for three things:

- a pending window whose end passes while nothing arrives (a tap's events stop long before
  onset + 250 ms): it is due when the stream clock, the newest data's stream time plus the
  host time elapsed since it arrived, less ``slack_ns`` for data still in flight, reaches it;
- the stream timeout: no data for ``timeout_ns`` flushes the pending windows as truncated;
- a stall of the liveness account (:mod:`.liveness`): silence while streaming turns WARN after
  ``warn_ns`` and ERROR after ``error_ns``, published at once.

The node keeps one one-shot timer armed for the earliest of these (:func:`next_wake_ns`)
instead of the former 1 ms polling timer, which cost 12 % of a core with nothing to do.
"""

from __future__ import annotations

from ext_sense_perception.online.liveness import StreamLiveness

MARGIN_NS = 100_000
"""Wake this long after a liveness threshold, so the check finds it passed (strictly greater)."""


def window_due_wall_ns(data_wall_ns: int, data_stream_ns: int, due_ns: int, slack_ns: int) -> int:
    """Host time at which the stream clock reaches ``due_ns`` if nothing else arrives.

    Args:
        data_wall_ns: Monotonic host time the newest data arrived.
        data_stream_ns: Its stream time (the newest event, or an empty batch's stamp).
        due_ns: Stream time the next window becomes due.
        slack_ns: Allowance for data still in flight.
    """
    return data_wall_ns + (due_ns - data_stream_ns) + slack_ns


def stall_change_ns(liveness: StreamLiveness, streaming: bool) -> int | None:
    """Monotonic time at which the liveness status changes if nothing arrives, or ``None``.

    While streaming and not stalled: when the silence passes ``warn_ns`` (a stall starts);
    while stalled and not yet ERROR: when it passes ``error_ns``; otherwise nothing to watch
    (the next message ends the stall, in the subscription callback).
    """
    if liveness.last_arrival_ns is None:
        return None
    if liveness.stalled_since_ns is not None:
        error_at = liveness.stalled_since_ns + liveness.error_ns + MARGIN_NS
        return error_at if liveness.clock() < error_at else None
    if streaming:
        return liveness.last_arrival_ns + liveness.warn_ns + MARGIN_NS
    return None


def next_wake_ns(
    *,
    data_wall_ns: int | None,
    data_stream_ns: int | None,
    due_ns: int | None,
    pending: bool,
    slack_ns: int,
    timeout_ns: int,
    stall_ns: int | None,
) -> int | None:
    """The earliest moment the node must act without new input (monotonic ns), or ``None``.

    Args:
        data_wall_ns: Monotonic host time the newest data arrived (``None`` before any).
        data_stream_ns: Stream time of that data (``None`` before any).
        due_ns: Stream time the next pending window becomes due when the stream clock may
            close it (NUSkin); ``None``: none, or windows closed only by data (BioTac frames).
        pending: Whether windows are pending (the stream timeout then flushes them).
        slack_ns: Allowance for data in flight when a window is closed by the clock.
        timeout_ns: No data this long flushes the pending windows.
        stall_ns: When the liveness status changes (:func:`stall_change_ns`).
    """
    wakes = [] if stall_ns is None else [stall_ns]
    if data_wall_ns is not None and data_stream_ns is not None:
        if due_ns is not None:
            wakes.append(window_due_wall_ns(data_wall_ns, data_stream_ns, due_ns, slack_ns))
        if pending:
            wakes.append(data_wall_ns + timeout_ns)
    return min(wakes) if wakes else None
