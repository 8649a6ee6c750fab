"""The protocol's splits and folds keep a trial's windows together (no leak between them)."""

from __future__ import annotations

import numpy as np
import pytest
from sklearn.model_selection import ShuffleSplit, StratifiedShuffleSplit

from ext_sense_perception.data.window_set import WindowSet
from ext_sense_perception.online.model_input import Geometry
from ext_sense_perception.training.protocol import evaluate, features_for, outer_splits
from ext_sense_runtime.stamps import MS


def _set(n_trials: int, copies: int, classes: bool) -> WindowSet:
    rng = np.random.default_rng(0)
    y_trial = (
        np.array(["a", "b"] * (n_trials // 2)) if classes else rng.uniform(0.02, 0.28, n_trials)
    )
    X = rng.poisson(1.0, (n_trials, 8, 60)).astype(np.float32)  # noqa: N806
    X[:, :, 20:30] += (10 * (y_trial == "a") if classes else 30 * y_trial)[:, None, None]
    reps = copies + 1
    return WindowSet(
        task="handover_stability" if classes else "tap_localization",
        sensor="nuskin",
        X=np.concatenate([X + rng.poisson(0.2, X.shape) for _ in range(reps)]),
        y=np.tile(y_trial, reps),
        geometry=Geometry(8, 60, MS, 20 * MS),
        class_names=("a", "b") if classes else (),
        groups=np.tile(np.arange(n_trials), reps),
        rod_length_m=np.full(n_trials * reps, 0.3),
        source="test",
        data_hash="0",
    )


@pytest.mark.parametrize("classes", [False, True])
def test_outer_splits_keep_each_trial_on_one_side(classes):
    ws = _set(40, 2, classes)
    splits = list(outer_splits(ws, 5, 0.1, 3))
    assert len(splits) == 5
    for train, test in splits:
        assert not set(ws.groups[train]) & set(ws.groups[test])
        assert len(train) + len(test) == len(ws.y)
        assert len(set(ws.groups[test])) == 4  # 10 % of the 40 trials, each with its 3 windows
        assert len(test) == 12
        if classes:
            assert set(ws.y[test]) == {"a", "b"}  # still stratified, by trial


@pytest.mark.parametrize("classes", [False, True])
def test_outer_splits_of_a_window_per_trial_are_the_plain_ones(classes):
    ws = _set(40, 0, classes)
    plain = (StratifiedShuffleSplit if classes else ShuffleSplit)(
        n_splits=5, test_size=0.1, random_state=3
    )
    for (a, b), (c, d) in zip(outer_splits(ws, 5, 0.1, 3), plain.split(ws.X, ws.y), strict=True):
        np.testing.assert_array_equal(a, c)
        np.testing.assert_array_equal(b, d)


def test_the_protocol_on_copies_searches_on_whole_trials():
    ws = _set(40, 2, classes=False)
    from ext_sense_perception.training.protocol import plan_evaluation

    plan = plan_evaluation(ws, features_for(ws, "baseline", bin_ns=5 * MS), "svm_linear", k=2)
    for t in plan.tasks:
        inner = ws.groups[t.train]
        assert isinstance(t.cv, list)
        assert len(t.cv) == 4
        for fit_idx, val_idx in t.cv:  # indices into the split's training part
            assert not set(inner[fit_idx]) & set(inner[val_idx])
    res = evaluate(
        ws, features_for(ws, "baseline", bin_ns=5 * MS), "svm_linear", k=2, progress=False
    )
    assert res.k == 2
    assert np.all(np.isfinite(res.scores))


@pytest.mark.parametrize(("trials", "copies", "folds"), [(200, 0, 10), (40, 0, 4), (100, 2, 5)])
def test_a_recipe_tap_model_scores_itself_on_more_folds_when_it_has_the_trials(
    trials, copies, folds
):
    from ext_sense_perception.training.fit import fit_model
    from ext_sense_perception.training.recipe import Recipe, fit_recipe

    ws = _set(trials, copies, classes=False)
    recipe = Recipe(features="baseline", feature_bin_ns=5 * MS, anytime_post_ns=())
    assert fit_recipe(ws, recipe)[0].card.metrics["cv_folds"] == folds
    # fit_model on its own keeps the paper's 4 (the report's deployed fits)
    plain = fit_model(ws, "baseline", "svm_rbf", feature_params={"bin_ns": 5 * MS}).card
    assert plain.metrics["cv_folds"] == 4
    classes = _set(200, 0, classes=True)
    assert fit_recipe(classes, recipe)[0].card.metrics["cv_folds"] == 4  # classes: the paper's


def test_a_model_trained_on_augmented_windows_is_scored_on_the_windows_as_cut():
    from ext_sense_perception.errors import PerceptionError
    from ext_sense_perception.training.fit import fit_model

    ws = _set(120, 0, classes=False)
    rng = np.random.default_rng(1)
    X = ws.X.copy()  # noqa: N806
    X[::2] += rng.normal(0.0, 3.0, X[::2].shape)  # half the windows blurred, as re-stamping does
    noisy = ws._replace(X=X)
    params = {"feature_params": {"bin_ns": 5 * MS}, "cv_folds": 5}
    same = fit_model(noisy, "baseline", "svm_rbf", as_cut=noisy, **params).card.metrics
    assert same["cv_mae_m"] == pytest.approx(same["cv_mae_augmented_m"])  # nothing told apart
    clean = fit_model(noisy, "baseline", "svm_rbf", as_cut=ws, **params).card.metrics
    assert clean["cv_mae_augmented_m"] == pytest.approx(same["cv_mae_augmented_m"])
    assert clean["cv_mae_m"] < clean["cv_mae_augmented_m"]  # the clean windows are easier
    with pytest.raises(PerceptionError, match="'as_cut' windows must be those of 'ws'"):
        fit_model(noisy, "baseline", "svm_rbf", as_cut=_set(60, 0, classes=False), **params)


def test_a_tap_recipe_that_restamps_keeps_both_scores_on_its_card():
    from ext_sense_perception.training.recipe import Recipe, fit_recipe

    ws = _set(80, 0, classes=False)
    recipe = Recipe(features="baseline", feature_bin_ns=5 * MS, anytime_post_ns=())
    metrics = fit_recipe(ws, recipe)[0].card.metrics  # the tap default re-stamps a quarter
    assert {"cv_mae_m", "cv_mae_augmented_m"} <= set(metrics)
    plain = fit_recipe(ws, Recipe(**{**recipe.__dict__, "arrival_jitter": 0.0}))[0].card.metrics
    assert "cv_mae_augmented_m" not in plain
