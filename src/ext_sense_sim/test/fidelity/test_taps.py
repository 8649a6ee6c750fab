import numpy as np
import pytest

from ext_sense_sim.fidelity.captures import Capture, read_tap_session, tap_folder
from ext_sense_sim.fidelity.errors import FidelityError
from ext_sense_sim.fidelity.taps import onset_bin, tap_windows, window_stats

# The synthetic capture (conftest.py): 80 quiet bins of 2 events on taxel 3, a bin of 20
# events, the onset bin of 400, then 24 bins of 100; window events cycle over taxel 1 (20 of
# 40), taxels 2-5 and taxels 41-56 (one each), one in four negative.


@pytest.mark.parametrize(
    ("counts", "expected"),
    [
        ([2, 3, 1, 40, 500, 300], 4),  # 20 % of 500 = 100: the bin of 40 is below it
        ([0, 29, 31, 50], 2),  # the floor of 30 events rules over 20 % of 50
        ([5, 29, 12], None),  # no bin reaches 30
        ([], None),
    ],
)
def test_onset_is_the_first_bin_over_max_30_and_a_fifth_of_the_busiest(counts, expected):
    assert onset_bin(np.array(counts, dtype=np.int64)) == expected


def test_a_capture_read_from_the_lab_format_gives_the_constructed_statistics(tmp_path, write_day):
    write_day(tmp_path / "day", 30, [1])
    session = read_tap_session(tmp_path / "day", 30)
    assert session.name == "day"
    (cap,) = session.captures
    assert cap.bins[0] == 0
    assert cap.mark_bin == -1
    w = tap_windows(session.captures)
    assert w.names == ["temp_signal0"]
    assert w.missed == []
    assert w.cut_short == []
    s = {k: v[0] for k, v in w.stats.items()}
    assert s["events"] == 2800
    assert s["first_30ms"] == pytest.approx(600 / 2800)
    assert s["last_100ms"] == pytest.approx(1000 / 2800)
    assert s["busiest_10"] == pytest.approx(29 / 40)
    assert s["finger_imbalance"] == pytest.approx(8 / 40)
    assert s["active_taxels"] == 21
    assert s["positive_share"] == pytest.approx(0.75)
    assert s["half_peak_ms"] == pytest.approx(10.0)
    assert s["taxel_rate_max"] == pytest.approx(1400 / 0.25)
    assert s["taxel_rate_median"] == pytest.approx(70 / 0.25)
    # 79 quiet bins of 2 before the guard of 20 ms ahead of the onset: 158 events in 0.79 s
    assert s["preroll_rate"] == pytest.approx(200.0)
    np.testing.assert_array_equal(w.profiles[0], [400] + [100] * 24)
    assert w.taxel_counts[0].sum() == 2800
    assert np.isnan(w.onset_error_ms[0])


def test_missed_taps_and_windows_past_the_capture_are_counted(tmp_path, write_day):
    write_day(tmp_path / "day", 20, [1, 2], missed=1)
    w = tap_windows(read_tap_session(tmp_path / "day", 20).captures)
    assert w.names == ["temp_signal0", "temp_signal1"]
    assert w.missed == ["temp_signal2"]
    assert w.stats["events"].tolist() == [2800, 400 * 2 + 2400 * 2]
    counts = [1, 1, 1, 1, 1, 1200, 100, 100, 100, 100]  # the capture ends 50 ms after the onset
    bins = np.repeat(np.arange(10), counts)
    n = bins.size
    ones = np.ones(n)
    short = Capture(
        "short",
        "",
        bins,
        (ones * 7).astype(np.uint16),
        ones.astype(np.int8),
        np.zeros(n, np.uint16),
        span_bins=10,
        mark_bin=5,
    )
    w = tap_windows([short])
    assert w.cut_short == ["short"]
    assert w.onset_error_ms.tolist() == [0.0]


def test_the_rate_spectrum_finds_a_12_hz_swell():
    n = np.arange(25)
    counts = np.round(200 + 150 * np.cos(2 * np.pi * 3 * n / 25)).astype(int)  # 12 Hz
    wbin = np.repeat(n, counts)
    stats, profile, _ = window_stats(wbin, np.ones(wbin.size, int), np.ones(wbin.size, int), 0, 0)
    assert profile.tolist() == counts.tolist()
    assert stats["spectrum_12_20hz"] > 0.99
    assert stats["spectrum_4_8hz"] + stats["spectrum_24_48hz"] < 0.01
    assert np.isnan(stats["preroll_rate"])


def test_real_folders_are_resolved_to_the_scene_rod_or_refused(tmp_path, write_day):
    write_day(tmp_path / "2021-03-24", 30, [1])
    assert tap_folder(tmp_path / "2021-03-24", 30) == ("2021-03-24", tmp_path / "2021-03-24/rod30")
    assert tap_folder(tmp_path / "2021-03-24" / "rod30", 30)[0] == "2021-03-24"
    with pytest.raises(
        FidelityError, match="holds captures of the 30 cm rod; the scene's rod is 50"
    ):
        tap_folder(tmp_path / "2021-03-24" / "rod30", 50)
    with pytest.raises(FidelityError, match=r"no rod-tap captures .* rod50/"):
        tap_folder(tmp_path / "2021-03-24", 50)
    with pytest.raises(FidelityError, match="does not exist"):
        tap_folder(tmp_path / "nowhere", 30)
    (tmp_path / "bad" / "rod30").mkdir(parents=True)
    (tmp_path / "bad" / "rod30" / "temp_signal0.tact").write_text("1 2 1\n")
    with pytest.raises(FidelityError, match="4 columns"):
        read_tap_session(tmp_path / "bad", 30)
