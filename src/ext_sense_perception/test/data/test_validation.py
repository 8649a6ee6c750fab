"""Poisoned input: a clear error naming file, row and rule, or (lenient) a counted drop."""

from __future__ import annotations

import numpy as np
import pytest

from ext_sense_perception.cli import register
from ext_sense_perception.data.importers import read_biotac_csv, read_capture_tact
from ext_sense_perception.data.sources import from_sim_dataset, load_window_set
from ext_sense_perception.data.validation import (
    RULE_EMPTY,
    RULE_LABEL,
    RULE_ORDER,
    RULE_TAXEL,
    RULE_TIME,
    RULE_VALUE,
    InputPolicy,
)
from ext_sense_perception.errors import PerceptionError

T0 = 1_617_248_000.0  # 1 April 2021, epoch seconds


def _capture(path, rows):
    """A capture file: start marker, ``col0 taxel value t`` rows, stop marker."""
    lines = [f"1 1 1 {T0:.2f}"] + [" ".join(str(v) for v in r) for r in rows]
    lines.append(f"2 2 2 {T0 + 5:.2f}")
    path.write_text("\n".join(lines) + "\n")
    return path


GOOD = [(0, 5, 512, f"{T0 + 0.01 * i:.2f}") for i in range(1, 6)]


@pytest.mark.parametrize(
    ("bad", "rule", "got"),
    [
        ((0, 5, 512, "nan"), RULE_TIME, "nan"),
        ((0, 5, 512, "inf"), RULE_TIME, "inf"),
        ((0, 5, 512, "-3.00"), RULE_TIME, "-3.0"),
        ((0, 0, 512, f"{T0 + 1:.2f}"), RULE_TAXEL, "0.0"),
        ((0, 81, 512, f"{T0 + 1:.2f}"), RULE_TAXEL, "81.0"),
        ((0, 70000, 512, f"{T0 + 1:.2f}"), RULE_TAXEL, "70000.0"),
        ((0, 2.5, 512, f"{T0 + 1:.2f}"), RULE_TAXEL, "2.5"),
        ((0, 5, -1, f"{T0 + 1:.2f}"), RULE_VALUE, "-1.0"),
        ((0, 5, 1024, f"{T0 + 1:.2f}"), RULE_VALUE, "1024.0"),
        ((0, 5, 512, f"{T0 - 1:.2f}"), RULE_ORDER, None),
    ],
)
def test_a_poisoned_capture_row_is_named_or_dropped(tmp_path, bad, rule, got):
    path = _capture(tmp_path / "apple_zero_0.tact", [*GOOD, bad, *GOOD[:0]])
    with pytest.raises(PerceptionError) as err:
        read_capture_tact(path)
    text = str(err.value)
    assert "apple_zero_0.tact" in text
    assert "row 6" in text
    assert rule in text
    if got is not None:
        assert got in text
    policy = InputPolicy(lenient=True)
    events = read_capture_tact(path, policy)
    assert events.size == len(GOOD)
    assert policy.dropped == {rule: 1}
    assert rule in policy.summary()


def test_a_clean_capture_passes_strictly(tmp_path):
    events = read_capture_tact(_capture(tmp_path / "a_zero_0.tact", GOOD))
    assert events.size == 5
    assert np.all(np.diff(events.t_ns) > 0)


def _sim_npz(path, *, taxel_fill=None, y_nan=False, n=12):
    rng = np.random.default_rng(0)
    ev_trial = np.repeat(np.arange(n), 30).astype(np.int32)
    ev_t = np.tile(np.arange(30) * 1_000_000 + 40_000_000, n).astype(np.int64)
    ev_taxel = rng.integers(1, 81, n * 30).astype(np.uint16)
    if taxel_fill is not None:
        ev_taxel[7] = taxel_fill
    y = rng.uniform(0.02, 0.28, n)
    if y_nan:
        y[3] = np.nan
    np.savez(
        path,
        task="tap_localization",
        sensor="nuskin",
        label_kind="regression",
        y=y,
        trial=np.arange(n, dtype=np.int32),
        onset_ns=np.full(n, 50_000_000, np.int64),
        rod_length_m=np.full(n, 0.3),
        ev_trial=ev_trial,
        ev_t_ns=ev_t,
        ev_taxel=ev_taxel,
        ev_polarity=np.ones(n * 30, np.int8),
        ev_value=np.zeros(n * 30, np.uint16),
    )
    return path


def test_sim_dataset_with_bad_taxels_or_labels_is_refused_or_dropped(tmp_path):
    bad_taxel = _sim_npz(tmp_path / "taxel.npz", taxel_fill=0)
    with pytest.raises(PerceptionError, match=rf"'ev_taxel'.*row 8: {RULE_TAXEL}"):
        from_sim_dataset(bad_taxel)
    policy = InputPolicy(lenient=True)
    ws = from_sim_dataset(bad_taxel, policy=policy)
    assert len(ws.y) == 12
    assert policy.dropped == {RULE_TAXEL: 1}

    nan_label = _sim_npz(tmp_path / "label.npz", y_nan=True)
    with pytest.raises(PerceptionError, match=rf"row 4: {RULE_LABEL}"):
        load_window_set(nan_label)
    policy = InputPolicy(lenient=True)
    ws = load_window_set(nan_label, policy=policy)
    assert len(ws.y) == 11
    assert np.isfinite(ws.y).all()
    assert ws.excluded == ("trial 3",)
    assert policy.dropped == {RULE_LABEL: 1}


def test_cli_train_stops_on_poison_and_lenient_prints_counts(tmp_path, capsys):
    import argparse

    parser = argparse.ArgumentParser()
    register(parser.add_subparsers())
    data = _sim_npz(tmp_path / "d.npz", taxel_fill=9999)
    args = parser.parse_args(["train", "--data", str(data), "--out", str(tmp_path / "m")])
    assert args.func(args) == 2
    assert RULE_TAXEL in capsys.readouterr().err
    assert not (tmp_path / "m").exists()
    args = parser.parse_args(
        [
            "train",
            "--data",
            str(data),
            "--out",
            str(tmp_path / "m"),
            "--lenient",
            "--anytime-ms",
            "none",
        ]
    )
    assert args.func(args) == 0
    assert f"dropped 1 x {RULE_TAXEL}" in capsys.readouterr().err


def test_all_nan_capture_is_an_empty_trial(tmp_path):
    path = _capture(tmp_path / "water_zero_1.tact", [(0, 5, 512, "nan")] * 4)
    policy = InputPolicy(lenient=True)
    assert read_capture_tact(path, policy).size == 0
    assert policy.dropped == {RULE_TIME: 4}
    from ext_sense_perception.data.validation import check_trial_not_empty

    with pytest.raises(PerceptionError, match=RULE_EMPTY):
        check_trial_not_empty(0, str(path), InputPolicy())
    assert not check_trial_not_empty(0, str(path), policy)
    assert policy.dropped[RULE_EMPTY] == 1


def test_biotac_csv_rows_are_checked(tmp_path):
    path = tmp_path / "b.csv"
    path.write_text("pac,t\n2000,1.0\n2001,1.1\n5000,1.2\n")
    with pytest.raises(PerceptionError, match=r"b.csv.*row 3: sample is not"):
        read_biotac_csv(path)
    path.write_text("pac,t\n2000,1.0\n2001,0.9\n")
    with pytest.raises(PerceptionError, match=rf"row 2: {RULE_ORDER}"):
        read_biotac_csv(path)
