# ruff: noqa: N803, N806
from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays
from sklearn.exceptions import NotFittedError

from ext_sense_perception.data.refractory import refractory_mask
from ext_sense_perception.errors import PerceptionError
from ext_sense_perception.features.est_kernel import est_kernel, fit_est_kernel
from ext_sense_perception.features.maps import FeatureKind, decimation_indices, select_channels
from ext_sense_perception.features.transformer import FFTFeatures, WindowFeatures, make_features
from ext_sense_perception.online.model_input import Geometry, as_model_input
from ext_sense_perception.online.window import ContactWindow
from ext_sense_runtime.stamps import MS

KINDS = [k.name.lower() for k in FeatureKind]


def _tf(kind: str, **kw) -> WindowFeatures:
    params = {"n_channels": 80, "n_samples": 300, "period_ns": MS, "pre_ns": 50 * MS}
    params.update(kw)
    return make_features(kind, **params)


def _windows(n: int = 6, seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return rng.integers(-2, 3, (n, 80 * 300)).astype(np.float32)


@pytest.mark.parametrize("kind", KINDS)
def test_every_kind_gives_finite_features_of_declared_size(kind):
    X = _windows()
    tf = _tf(kind, **({"ae_max_iter": 20} if kind == "autoencoder" else {})).fit(X)
    F = tf.transform(X)
    assert F.shape == (6, tf.n_features_out_)
    assert np.isfinite(F).all()


def test_the_autoencoder_trains_in_float32_and_codes_in_float64():
    X = _windows()
    tf = _tf("autoencoder", ae_max_iter=20).fit(X)
    assert all(w.dtype == b.dtype == np.float64 for w, b in tf.ae_layers_)
    F = tf.transform(X)
    assert F.dtype == np.float64
    # the stored layers are the float32 net's own weights: its code, recomputed by hand
    h = (FFTFeatures._features(tf, X.reshape(6, 80, -1)) - tf.ae_mean_) / tf.ae_scale_
    for w, b in tf.ae_layers_:
        assert np.array_equal(w, w.astype(np.float32).astype(np.float64))
        h = np.maximum(h @ w + b, 0.0)
    np.testing.assert_allclose(F, h, rtol=1e-12, atol=1e-12)


def test_baseline_is_rebinned_signed_counts():
    X = _windows(2)
    F = _tf("baseline", bin_ns=5 * MS).fit(X).transform(X)
    expected = X.reshape(2, 80, 60, 5).sum(axis=3).reshape(2, -1)
    np.testing.assert_allclose(F, expected)


def test_fft_matches_numpy_with_paper_scaling():
    X = _windows(2)
    F = _tf("fft", bin_ns=5 * MS).fit(X).transform(X)
    binned = X.reshape(2, 80, 60, 5).sum(axis=3).astype(np.float64)
    expected = (np.abs(np.fft.rfft(binned / 1000.0, axis=2)) / 10.0).reshape(2, -1)
    np.testing.assert_allclose(F, expected, rtol=1e-9, atol=1e-12)


def test_biotac_fft_with_decimation():
    rng = np.random.default_rng(0)
    X = rng.normal(2000, 30, (3, 660))
    tf = FFTFeatures(
        n_channels=1,
        n_samples=660,
        period_ns=454_545,
        pre_ns=110 * 454_545,
        sensor="biotac",
        rate_hz=500,
    )
    F = tf.fit(X).transform(X)
    idx = decimation_indices(660, 500, 1e9 / 454_545)
    expected = np.abs(np.fft.rfft(X[:, idx] / 1000.0, axis=1)) / 10.0
    np.testing.assert_allclose(F, expected, rtol=1e-9)


def test_activity_features_for_food():
    X = np.zeros((1, 80 * 300), np.float32)
    X[0, 5 * 300 + 250] = 3  # taxel 6, 2.5 s into a 3 s window at 10 ms bins
    tf = _tf("activity", period_ns=10 * MS, pre_ns=0, activity_late_ns=2000 * MS).fit(X)
    F = tf.transform(X)
    over_time = F[0, :12]
    assert over_time[10] == pytest.approx(np.log1p(3))
    assert over_time.sum() == pytest.approx(np.log1p(3))
    per_taxel = F[0, 12:].reshape(80, 2)
    assert per_taxel[5, 0] == pytest.approx(np.log1p(3))
    assert per_taxel[5, 1] == pytest.approx(np.log1p(3))
    assert per_taxel.sum() == pytest.approx(2 * np.log1p(3))


def test_channel_selection_one_finger_and_single_taxel():
    assert list(select_channels("left", 80)) == list(range(40))
    assert list(select_channels("right", 80)) == list(range(40, 80))
    assert list(select_channels("taxel:7", 80)) == [6]
    assert list(select_channels("ids:1,80", 80)) == [0, 79]
    with pytest.raises(PerceptionError, match="'channels'"):
        select_channels("taxel:81", 80)
    with pytest.raises(PerceptionError, match="'channels'"):
        select_channels("thumb", 80)
    X = _windows(2)
    one = _tf("baseline", channels="taxel:7").fit(X).transform(X)
    assert one.shape == (2, 60)
    np.testing.assert_allclose(one, X.reshape(2, 80, 60, 5)[:, 6].sum(axis=2))


def test_refractory_mask_drops_spikes_closer_than_tau_per_taxel():
    t = np.array([0, 100_000, 300_000, 400_000, 1_000_000, 50_000], np.int64)
    tax = np.array([1, 1, 1, 1, 1, 2])
    order = np.argsort(t)
    keep = refractory_mask(t[order], tax[order], rate_hz=4000)  # tau = 250 us
    kept = sorted(zip(t[order][keep], tax[order][keep], strict=True))
    assert kept == [(0, 1), (50_000, 2), (300_000, 1), (1_000_000, 1)]
    with pytest.raises(PerceptionError, match="'rate_hz'"):
        refractory_mask(t, tax, 0)


def test_decimation_indices_and_errors():
    idx = decimation_indices(660, 1100, 2200)
    assert idx[0] == 0
    assert idx[-1] == 659
    assert len(idx) == 331
    assert list(decimation_indices(10, 2200, 2200)) == list(range(10))
    with pytest.raises(PerceptionError, match="'rate_hz'"):
        decimation_indices(10, 5000, 2200)


def test_est_kernel_fits_decaying_exponential():
    w = fit_est_kernel(tau_s=0.005, span_s=0.05)
    lags = np.array([0.0, 0.005, 0.02])
    k = est_kernel(lags, w)
    np.testing.assert_allclose(k, np.exp(-lags / 0.005), atol=0.08)


def test_nan_and_shape_rejected_with_clear_errors():
    X = _windows(1)
    tf = _tf("fft").fit(X)
    bad = X.copy()
    bad[0, 10] = np.nan
    with pytest.raises(PerceptionError, match="finite"):
        tf.transform(bad)
    bad[0, 10] = np.inf
    with pytest.raises(PerceptionError, match="finite"):
        tf.transform(bad)
    with pytest.raises(PerceptionError, match="shape"):
        tf.transform(X[:, :100])
    with pytest.raises(NotFittedError, match="not fitted"):
        _tf("fft").transform(X)
    with pytest.raises(PerceptionError, match="'features'"):
        _tf("wavelets").fit(X)
    with pytest.raises(PerceptionError, match="no parameter"):
        _tf("activity", bin_ns=5 * MS)


def test_as_model_input_crops_and_rebins_online_windows():
    g = Geometry(80, 300, MS, 50 * MS, "nuskin")
    rng = np.random.default_rng(0)
    fine = rng.integers(-1, 2, (80, 1400)).astype(
        np.float32
    )  # 0.25 ms bins, 100 ms pre, 250 ms post
    win = ContactWindow(
        "tap_localization", "nuskin", 0, 100 * MS, 250 * MS, 250_000, np.arange(1, 81), fine
    )
    row = as_model_input(win, g).reshape(80, 300)
    np.testing.assert_array_equal(row, fine[:, 200:1400].reshape(80, 300, 4).sum(axis=2))
    short = win._replace(data=fine[:, :600], post_onset_ns=50 * MS)
    with pytest.raises(PerceptionError, match="at least"):
        as_model_input(short, g)
    with pytest.raises(PerceptionError, match="sample_period_ns"):
        as_model_input(win._replace(sample_period_ns=300_000), g)
    with pytest.raises(PerceptionError, match="channels"):
        as_model_input(fine[:40], g)


@settings(max_examples=25, deadline=None)
@given(arrays(np.float32, (2, 80 * 300), elements=st.floats(-1e4, 1e4, width=32)))
def test_float32_and_float64_inputs_agree(X):
    tf = _tf("fft").fit(X)
    a = tf.transform(X.astype(np.float32))
    b = tf.transform(X.astype(np.float64))
    np.testing.assert_allclose(a, b, rtol=1e-6, atol=1e-9)


@settings(max_examples=20, deadline=None)
@given(st.sampled_from(["baseline", "fft", "est", "activity"]), st.floats(0, 1e6))
def test_constant_and_saturated_windows_give_finite_features(kind, level):
    X = np.full((2, 80 * 300), level, np.float32)
    F = _tf(kind).fit(X).transform(X)
    assert np.isfinite(F).all()


def test_gauss_bins_weigh_like_box_bins_away_from_the_ends():
    from ext_sense_perception.features.maps import gauss_rebin_matrix, rebin_matrix

    g, b = gauss_rebin_matrix(300, 5), rebin_matrix(300, 5)
    assert g.shape == b.shape == (300, 60)
    np.testing.assert_allclose(g.sum(axis=0)[5:-5], 5.0, rtol=1e-3)  # a constant series
    assert np.argmax(g[:, 20]) in (102, 103)  # bin 20 is centred on its own samples


def test_gauss_bins_hold_the_spectrum_when_the_onset_moves():
    """A burst moved by 2 of 5 samples in a bin: box bins swap whole events, Gaussian ones not."""
    rng = np.random.default_rng(3)
    x = np.zeros((80, 300), np.float32)
    x[:, 50:200] = rng.poisson(2.0 * np.exp(-np.arange(150) / 40.0), (80, 150))
    moved = np.zeros_like(x)
    moved[:, 2:] = x[:, :-2]
    change = {}
    for kernel in ("box", "gauss"):
        tf = _tf("fft", bin_ns=5 * MS, bin_kernel=kernel).fit(x.reshape(1, -1))
        a, b = (tf.transform(w.reshape(1, -1))[0] for w in (x, moved))
        change[kernel] = np.linalg.norm(a - b) / np.linalg.norm(a)
    assert change["gauss"] < 0.05 * change["box"]


def test_a_taper_lets_the_events_at_the_window_end_go_and_keeps_the_rest():
    """A rod rings past the window's end, so an onset moved by 2 ms brings events in or drops
    them there: with tapered ends they barely change the features; mid-window events count as
    before. Taper 0 is the paper's features, unchanged."""
    rng = np.random.default_rng(4)
    t = np.arange(300)
    rate = 2.0 * np.exp(-(t - 50) / 200.0) * (1 + np.sin(2 * np.pi * t / 40.0)) * (t >= 50)
    x = rng.poisson(rate, (80, 300)).astype(np.float32)
    at_end, mid = x.copy(), x.copy()
    at_end[:, -2:] += rng.poisson(3.0, (80, 2))
    mid[:, 100:102] += rng.poisson(3.0, (80, 2))
    change = {}
    for taper in (0.0, 0.2):
        tf = _tf("fft", bin_ns=5 * MS, bin_kernel="gauss", taper=taper).fit(x.reshape(1, -1))
        a, end, middle = (tf.transform(w.reshape(1, -1))[0] for w in (x, at_end, mid))
        change[taper] = [np.linalg.norm(a - b) / np.linalg.norm(a) for b in (end, middle)]
    assert change[0.2][0] < 0.1 * change[0.0][0]  # 0.001 against 0.036
    assert change[0.2][1] == pytest.approx(change[0.0][1], rel=0.2)  # 0.041 against 0.040
    plain = _tf("fft", bin_ns=5 * MS).fit(x.reshape(1, -1))
    zero = _tf("fft", bin_ns=5 * MS, taper=0.0).fit(x.reshape(1, -1))
    np.testing.assert_array_equal(
        plain.transform(x.reshape(1, -1)), zero.transform(x.reshape(1, -1))
    )


@pytest.mark.parametrize("taper", [-0.1, 1.5, "hann"])
def test_a_taper_outside_zero_to_one_is_refused(taper):
    with pytest.raises(PerceptionError, match="'taper' parameter must be a share in"):
        _tf("fft", taper=taper).fit(_windows())


def test_an_unknown_bin_kernel_is_refused():
    with pytest.raises(PerceptionError, match="'bin_kernel' parameter must be one of box, gauss"):
        _tf("fft", bin_kernel="hann").fit(_windows())
