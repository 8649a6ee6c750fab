"""A taxel stuck at its ceiling is found, masked from onset detection and never a contact."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from ext_sense_perception.errors import PerceptionError
from ext_sense_perception.online.stuck_taxels import StuckTaxels
from ext_sense_perception.online.window import WindowConfig
from ext_sense_perception.online.windowers import EventWindower
from ext_sense_runtime.records import EventBlock
from ext_sense_runtime.stamps import MS

EPOCH = 1_700_000_000_000_000_000
STUCK = 17


def _stuck(start_ms: int, end_ms: int, taxel: int = STUCK, rate_hz: float = 4000.0):
    """One taxel firing at ``rate_hz`` from ``start_ms`` to ``end_ms`` (stream ms)."""
    t = EPOCH + np.arange(start_ms * MS, end_ms * MS, int(1e9 / rate_hz), dtype=np.int64)
    return t, np.full(t.size, taxel, np.uint16)


def _tap(onset_ms: int, rng: np.random.Generator):
    """A real contact: 400 events over 40 taxels in 30 ms."""
    t = EPOCH + onset_ms * MS + np.sort(rng.integers(0, 30 * MS, 400))
    return t.astype(np.int64), rng.integers(1, 41, t.size).astype(np.uint16)


def _feed(w: EventWindower, t: np.ndarray, tax: np.ndarray, end_ms: int) -> list:
    """Feed in 1 ms packets, each closed at its end (as the driver's packets), to ``end_ms``."""
    order = np.argsort(t, kind="stable")
    t, tax = t[order], tax[order]
    out = []
    edges = np.searchsorted(t, EPOCH + np.arange(0, end_ms + 1) * MS)
    for ms in range(end_ms):
        lo, hi = edges[ms], edges[ms + 1]
        block = EventBlock.of(t[lo:hi], tax[lo:hi], np.ones(hi - lo, np.int8))
        out += w.feed(block, now_ns=EPOCH + (ms + 1) * MS)
    return out


def test_a_taxel_at_its_ceiling_longer_than_after_is_stuck_until_a_quiet_bucket():
    guard = StuckTaxels(80, rate_hz=2000.0, after_ns=1000 * MS)
    t, tax = _stuck(0, 1500)
    changed = [guard.feed(t[i : i + 4], tax[i : i + 4]) for i in range(0, t.size, 4)]
    assert guard.ids == (STUCK,)
    assert sum(changed) == 1  # once, when it became stuck
    assert guard.stuck_for_ns(STUCK) >= 1000 * MS
    assert guard.last_rate_hz[STUCK] == pytest.approx(4000.0)
    assert not guard.advance(EPOCH + 1550 * MS)  # the bucket still open
    assert guard.advance(EPOCH + 1700 * MS)  # closed, then a whole bucket without an event
    assert guard.ids == ()


def test_contacts_as_long_as_real_ones_are_never_stuck():
    # real rod taps (24-25 March 2021): a taxel at >= 2000 events/s for 300 ms at most
    guard = StuckTaxels(80, rate_hz=2000.0, after_ns=1000 * MS)
    for start in range(0, 10_000, 500):
        t, tax = _stuck(start, start + 400)
        assert not guard.feed(t, tax)
    assert guard.ids == ()


def test_stuck_taxels_refuses_a_non_positive_setting():
    with pytest.raises(PerceptionError, match=r"'after_ns' parameter must be > 0\. Got 0"):
        StuckTaxels(80, rate_hz=2000.0, after_ns=0)


def test_one_stuck_taxel_alone_triggers_no_contact_and_is_masked():
    w = EventWindower(WindowConfig.for_task("tap_localization", "nuskin"))
    t, tax = _stuck(0, 5000)
    windows = _feed(w, t, tax, 5000)
    assert windows == []
    assert w.counters.onsets == 0
    assert w.counters.one_taxel_bursts > 0  # refused as one taxel before it was masked
    assert w.stuck.ids == (STUCK,)
    assert w.stuck.masked_events > 0


def test_without_the_taxel_rule_the_mask_still_ends_the_false_contacts_after_a_second():
    config = replace(WindowConfig.for_task("tap_localization", "nuskin"), activity_min_taxels=1)
    w = EventWindower(config)
    t, tax = _stuck(0, 5000)
    windows = [x for x in _feed(w, t, tax, 5000) if not x.provisional]
    assert windows  # the former detector: a contact every debounce
    assert max(x.onset_ns for x in windows) < EPOCH + 1200 * MS


def test_real_taps_beside_a_stuck_taxel_are_found_and_their_windows_degraded():
    rng = np.random.default_rng(3)
    st, sk = _stuck(0, 4000)
    taps = [_tap(ms, rng) for ms in (500, 2000, 3000)]
    t = np.concatenate([st, *(a for a, _ in taps)])
    tax = np.concatenate([sk, *(b for _, b in taps)])
    w = EventWindower()
    finals = [x for x in _feed(w, t, tax, 4000) if not x.provisional]
    onsets = [x.onset_ns for x in finals]
    firsts = [int(a[b != STUCK][0]) for a, b in taps]  # its events are masked in taps too
    # before it is masked the stuck taxel may open the burst: within the 2 ms activity window
    assert 0 <= firsts[0] - onsets[0] <= 2 * MS
    assert onsets[1:] == firsts[1:]  # masked: the tap's own first event
    assert [x.degraded for x in finals] == [False, True, True]  # stuck from 1 s on
    assert finals[1].degraded_reason == (
        f"stuck taxel(s) {STUCK} in the window (masked from onset detection)"
    )
    assert w.counters.stuck_taxel_windows >= 2


def test_a_burst_of_fewer_taxels_than_activity_min_taxels_is_no_onset():
    config = replace(WindowConfig.for_task("tap_localization", "nuskin"), activity_min_taxels=3)
    a, ta = _stuck(100, 104, taxel=5)
    b, tb = _stuck(100, 104, taxel=6)
    w = EventWindower(config)
    _feed(w, np.concatenate([a, b]), np.concatenate([ta, tb]), 400)
    assert w.counters.onsets == 0
    c, tc = _stuck(200, 204, taxel=7)
    w = EventWindower(config)
    _feed(w, np.concatenate([a + 100 * MS, b + 100 * MS, c]), np.concatenate([ta, tb, tc]), 400)
    assert w.counters.onsets == 1


@pytest.mark.parametrize(
    ("change", "match"),
    [
        ({"activity_min_taxels": 0}, "'activity_min_taxels' parameter must be in \\[1, n_taxels"),
        ({"stuck_rate_hz": 0.0}, "'stuck_rate_hz' parameter must be > 0"),
        ({"stuck_after_ns": -1}, "'stuck_after_ns' parameter must be > 0"),
    ],
)
def test_the_window_config_refuses_bad_stuck_taxel_settings(change, match):
    with pytest.raises(PerceptionError, match=match):
        replace(WindowConfig.for_task("tap_localization", "nuskin"), **change)


def test_the_taxels_status_names_the_stuck_ids_with_units_and_clears():
    from ext_sense_runtime.diagnostics import Level

    w = EventWindower()
    assert w.stuck_status()[:2] == (Level.OK, "ok")
    t, tax = _stuck(0, 2000)
    _feed(w, t, tax, 2000)
    level, message, values = w.stuck_status()
    assert level == Level.WARN
    assert message == (
        f"stuck taxel(s) {STUCK}: 4000 events/s for {values['stuck_for_s']} s; masked from onset "
        "detection until they quiet"
    )
    assert values["stuck_taxel_ids"] == str(STUCK)
    assert float(values["stuck_for_s"]) >= 1.0
    assert values["stuck_after_ms"] == "1000"
    assert values["one_taxel_bursts_refused"] > 0
    w.feed(EventBlock.of(t[:0], tax[:0], t[:0].astype(np.int8)), now_ns=EPOCH + 2300 * MS)
    assert w.stuck_status()[:2] == (Level.OK, "ok")  # a quiet bucket: it detects onsets again
