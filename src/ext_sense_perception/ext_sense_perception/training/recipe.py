"""The one training recipe: a window set in, a saved bundle (with its anytime models) out.

Every trainer (``ext-sense train``, the demo, bags, tests) calls :func:`train_bundle`, so
bundles differ only in their windows and :class:`Recipe` choices.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any, NamedTuple

from ext_sense_perception.data.window_set import WindowSet
from ext_sense_perception.errors import PerceptionError
from ext_sense_perception.features.maps import FeatureKind
from ext_sense_perception.features.transformer import FAMILIES
from ext_sense_perception.online.model_card import ModelCard
from ext_sense_perception.training.arrival_jitter import augment, default_fraction, onset_shifted
from ext_sense_perception.training.bundle_io import save_bundle
from ext_sense_perception.training.fit import TrainedModel, fit_anytime, fit_model
from ext_sense_perception.training.models import default_choice, default_feature_grid
from ext_sense_runtime.enums import Task

REGRESSION_FOLDS = 10
"""Grid-search folds of a tap model the recipe trains: with the paper's 4, the card's CV MAE
was that of a model on three quarters of the taps (docs/perception.md).
"""

DEFAULT_BIN_KERNEL: dict[Task, str] = {Task.TAP_LOCALIZATION: "gauss"}
"""The NUSkin feature-bin kernel when the recipe names none, by task (others: the paper's
``box``). Gaussian bins move a tap estimate far less when the arrival clock moves the onset
(docs/perception.md, ``bench/bench_window_shift.py``).
"""


DEFAULT_TAPER: dict[Task, float] = {Task.TAP_LOCALIZATION: 0.2}
"""The NUSkin FFT features' Tukey taper share when the recipe names none, by task (others: 0,
the paper's). Tapered ends halve how far a tap estimate moves when the onset moves by 2 ms, at
the same fresh-tap error (docs/perception.md, ``bench/bench_window_shift.py``).
"""


@dataclass(frozen=True)
class Recipe:
    """The choices of a training run; every default (None) is the task's own.

    ``channels`` selects channels (``all``, ``left``, ``right``, ``taxel:N``, ``ids:a,b``);
    ``rate_hz`` is the rate the windows were reduced to (BioTac decimates in the features; for
    NUSkin the card only records it). ``anytime_post_ns`` ``()`` trains no anytime models.
    ``arrival_jitter`` is the fraction of NUSkin windows re-stamped with the measured arrival jitter
    (default :data:`~.arrival_jitter.DEFAULT_FRACTION`); ``bin_kernel`` ``box`` or ``gauss``
    (default :data:`DEFAULT_BIN_KERNEL`); ``taper`` the FFT features' Tukey taper share
    (default :data:`DEFAULT_TAPER`); ``onset_shifts`` adds copies of each NUSkin window at onsets
    moved by up to 2 ms.
    """

    features: str | None = None
    model: str | None = None
    channels: str | None = None
    feature_bin_ns: int | None = None
    rate_hz: float | None = None
    anytime_post_ns: tuple[int, ...] | None = None
    seed: int = 0
    n_jobs: int = 1
    arrival_jitter: float | None = None
    bin_kernel: str | None = None
    taper: float | None = None
    onset_shifts: int = 0


class Choice(NamedTuple):
    """What a recipe resolves to for one window set."""

    features: str
    model: str
    feature_params: dict[str, Any]
    feature_grid: dict[str, list[Any]]


def resolve(ws: WindowSet, recipe: Recipe) -> Choice:
    """The feature set, model, fixed feature parameters and feature grid for ``ws``."""
    features, model = default_choice(ws.task, ws.sensor)
    features = recipe.features or features
    model = recipe.model or model
    params: dict[str, Any] = {}
    if recipe.channels:
        params["channels"] = recipe.channels
    if recipe.feature_bin_ns is not None:
        params["bin_ns"] = int(recipe.feature_bin_ns)
    if recipe.rate_hz is not None and ws.sensor == "biotac":
        params["rate_hz"] = float(recipe.rate_hz)
    task = Task.parse(ws.task, PerceptionError)
    kernel = recipe.bin_kernel or DEFAULT_BIN_KERNEL.get(task)
    taper = DEFAULT_TAPER.get(task, 0.0) if recipe.taper is None else recipe.taper
    family_params = FAMILIES[FeatureKind.parse(features)]._get_param_names()
    if ws.sensor == "nuskin":
        if kernel and "bin_kernel" in family_params:
            params["bin_kernel"] = kernel
        if taper and "taper" in family_params:
            params["taper"] = float(taper)
    return Choice(features, model, params, default_feature_grid(ws.task, ws.sensor, features))


def fit_recipe(ws: WindowSet, recipe: Recipe = Recipe()) -> tuple[TrainedModel, list[TrainedModel]]:
    """The model and its anytime models the recipe fits on ``ws``, not yet saved."""
    fraction = default_fraction(ws.task) if recipe.arrival_jitter is None else recipe.arrival_jitter
    as_cut = ws
    if fraction:
        ws = augment(ws, fraction, recipe.seed)
    if recipe.onset_shifts:  # copies: the card scores the augmented folds
        ws = onset_shifted(ws, recipe.onset_shifts, seed=recipe.seed)
        as_cut = None
    elif ws is as_cut:
        as_cut = None  # nothing re-stamped
    choice = resolve(ws, recipe)
    kwargs: dict[str, Any] = {
        "feature_params": choice.feature_params,
        "feature_grid": choice.feature_grid,
        "seed": recipe.seed,
        "n_jobs": recipe.n_jobs,
        "rate_hz": recipe.rate_hz,
        "cv_folds": REGRESSION_FOLDS,
    }
    trained = fit_model(ws, choice.features, choice.model, as_cut=as_cut, **kwargs)
    posts = (
        ws.task_profile.anytime_post_ns
        if recipe.anytime_post_ns is None
        else tuple(recipe.anytime_post_ns)
    )
    anytime = fit_anytime(ws, choice.features, choice.model, posts, **kwargs)
    return trained, anytime


def train_bundle(ws: WindowSet, out: str | Path, recipe: Recipe = Recipe()) -> ModelCard:
    """Train the recipe's model and anytime models on ``ws`` and save them as a bundle in ``out``.

    PerceptionError: too few windows or classes, unknown features or model, failed export.
    """
    trained, anytime = fit_recipe(ws, recipe)
    save_bundle(trained, out, anytime, windows=ws)
    return trained.card
