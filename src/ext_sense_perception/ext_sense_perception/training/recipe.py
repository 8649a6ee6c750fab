"""The one training recipe: a window set in, a saved bundle (with its anytime models) out.

``ext-sense train``, the demo (on the device stream or a simulated dataset), training from bags
and the tests all call :func:`train_bundle`, so a bundle differs from another only in its
windows and the :class:`Recipe` choices, never in how it was trained. What the recipe fixes:

- features and model: the task's default (:func:`~.models.default_choice`) unless named;
- feature parameters: the task profile's feature bin (see :func:`~.protocol.features_for`), a
  channel selection, a BioTac decimation rate, and the default grid of feature parameters
  searched inside the folds (:func:`~.models.default_feature_grid`);
- anytime models for the task profile's anytime post-contact times;
- the grid search with K-fold CV (4 folds for classes, :data:`REGRESSION_FOLDS` for tap
  positions) and refit of :func:`~.fit.fit_model`;
- NUSkin feature bins: the task's kernel (:data:`DEFAULT_BIN_KERNEL`) unless named: tap
  localisation bins with Gaussian weights, so a window whose onset the arrival clock moves by a
  millisecond or two gives nearly the same estimate (``bench/bench_window_shift.py``);
- optionally, arrival-jitter augmentation (``arrival_jitter``): a fraction of the NUSkin windows
  re-stamped as a late reader stamps them (:mod:`.arrival_jitter`, the read delays measured by
  ``bench/bench_arrival.py``), and copies of each window at onsets moved by up to 2 ms
  (``onset_shifts``), before the fit and the anytime fits.
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
"""Grid-search folds of a tap model the recipe trains, whose card's CV MAE is its promise: a
fold's model learns from (k - 1) / k of the taps and a tap model's error still falls with more
taps, so with 4 folds (the paper's protocol) the CV MAE was that of a model on three quarters
of them, about a tenth worse than the model fitted on all did on fresh taps; with 10 folds a
few percent (``bench/bench_window_shift.py``)."""

DEFAULT_BIN_KERNEL: dict[Task, str] = {Task.TAP_LOCALIZATION: "gauss"}
"""The NUSkin feature-bin kernel when the recipe names none, by task (others: ``box``, the
paper's). Taps: on box bins an onset moved by 2 ms (a serial link's arrival clock) moved the
FFT + SVR estimate by more than half a centimetre, on Gaussian bins by a fifth of that, at the
same accuracy on fresh taps (``bench/bench_window_shift.py``)."""


@dataclass(frozen=True)
class Recipe:
    """The choices of a training run; every default is the task's own.

    Attributes:
        features: Feature family (None: the task's default).
        model: Model name (None: the task's default).
        channels: Channel selection (``all``, ``left``, ``right``, ``taxel:N``, ``ids:a,b``).
        feature_bin_ns: NUSkin feature bin, ns (None: the task profile's).
        rate_hz: Rate the windows were reduced to: BioTac decimates in the features; NUSkin
            windows were thinned by the data source, the card records the rate.
        anytime_post_ns: Post-contact times of the anytime models, ns (None: the task
            profile's; ``()``: none).
        seed: Seed of folds and models (and of the augmentation).
        n_jobs: Grid-search jobs.
        arrival_jitter: Fraction of NUSkin training windows re-stamped in place with the
            measured arrival jitter (0: none; BioTac windows are never touched; None: the
            task's :data:`~.arrival_jitter.DEFAULT_FRACTION`, 0.5 for handover, where it
            lifts accuracy on jittered windows at no cost on clean ones, 0 for taps and food,
            where it does not help; docs/perception.md, "Arrival jitter").
        bin_kernel: NUSkin feature-bin kernel, ``box`` or ``gauss`` (None: the task's
            :data:`DEFAULT_BIN_KERNEL`); families without bins ignore it.
        onset_shifts: Copies of each NUSkin window (signal onsets only) added with the onset
            moved by up to 2 ms (:func:`~.arrival_jitter.onset_shifted`; 0: none).
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
    kernel = recipe.bin_kernel or DEFAULT_BIN_KERNEL.get(Task.parse(ws.task, PerceptionError))
    family = FAMILIES[FeatureKind.parse(features)]
    if kernel and ws.sensor == "nuskin" and "bin_kernel" in family._get_param_names():
        params["bin_kernel"] = kernel
    return Choice(features, model, params, default_feature_grid(ws.task, ws.sensor, features))


def fit_recipe(
    ws: WindowSet,
    recipe: Recipe = Recipe(),
) -> tuple[TrainedModel, list[TrainedModel]]:
    """The model and its anytime models the recipe fits on ``ws``, not yet saved."""
    fraction = default_fraction(ws.task) if recipe.arrival_jitter is None else recipe.arrival_jitter
    if fraction:
        ws = augment(ws, fraction, recipe.seed)
    if recipe.onset_shifts:
        ws = onset_shifted(ws, recipe.onset_shifts, seed=recipe.seed)
    choice = resolve(ws, recipe)
    kwargs: dict[str, Any] = {
        "feature_params": choice.feature_params,
        "feature_grid": choice.feature_grid,
        "seed": recipe.seed,
        "n_jobs": recipe.n_jobs,
        "rate_hz": recipe.rate_hz,
        "cv_folds": REGRESSION_FOLDS,
    }
    trained = fit_model(ws, choice.features, choice.model, **kwargs)
    posts = (
        ws.task_profile.anytime_post_ns
        if recipe.anytime_post_ns is None
        else tuple(recipe.anytime_post_ns)
    )
    anytime = fit_anytime(ws, choice.features, choice.model, posts, **kwargs)
    return trained, anytime


def train_bundle(
    ws: WindowSet,
    out: str | Path,
    recipe: Recipe = Recipe(),
) -> ModelCard:
    """Train the recipe's model and anytime models on ``ws`` and save them as a bundle.

    Args:
        ws: Labelled windows.
        out: Bundle directory.
        recipe: The choices (default: everything the task's own).

    Returns:
        The card of the saved bundle.

    Raises:
        PerceptionError: Too few windows or classes, an unknown feature set or model, or a
            failed ONNX export.
    """
    trained, anytime = fit_recipe(ws, recipe)
    save_bundle(trained, out, anytime, windows=ws)
    return trained.card
