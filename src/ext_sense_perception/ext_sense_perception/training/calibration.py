# ruff: noqa: N806  (X for the window matrix, as in scikit-learn)
"""Calibrating a bundle to a new session with a handful of its labelled trials (no ROS).

The bundle's training windows plus the session's trials, each repeated ``weight`` times, are
refitted through the recipe; the new card restricts decisions to the session's label set. A few
weighted trials move the boundaries to where the day's drifted readings put the classes
(docs/perception.md, "Sessions and calibration").
"""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any

import numpy as np

from ext_sense_perception.data.sessions import Session, pooled
from ext_sense_perception.data.window_set import WindowSet
from ext_sense_perception.errors import PerceptionError
from ext_sense_perception.online.model_card import ModelCard, read_card
from ext_sense_perception.training.bundle_io import TRAINING_WINDOWS_FILE, save_bundle
from ext_sense_perception.training.cross_session import fit_and_score, without_single_windows
from ext_sense_perception.training.recipe import Recipe, fit_recipe
from ext_sense_runtime.stamps import MS

DEFAULT_WEIGHT = 2
"""Repeats of each calibration trial in the refit: the fewest that lets a class seen in one
trial be calibrated (2 windows per class); 2, 5 and 10 measured alike.
"""


def training_windows(bundle: str | Path, card: ModelCard | None = None) -> WindowSet:
    """The windows a bundle was trained on (PerceptionError: none kept, or not the card's)."""
    card = card or read_card(bundle)
    path = Path(bundle) / TRAINING_WINDOWS_FILE
    if not path.is_file():
        raise PerceptionError(
            f"Bundle {str(bundle)!r} has no {TRAINING_WINDOWS_FILE}: it was trained before "
            "bundles kept their windows. Retrain it with ext-sense train to calibrate it."
        )
    try:
        with np.load(path, allow_pickle=False) as z:
            X, y = z["X"].astype(np.float32), z["y"]
            groups, rods, sessions = z["groups"], z["rod_length_m"], z["sessions"]
    except (OSError, KeyError, ValueError) as err:
        raise PerceptionError(f"Cannot read {str(path)!r}: {err}") from err
    w = card.window
    if X.shape[1:] != (w.n_channels, w.n_samples) or len(y) != card.n_train:
        raise PerceptionError(
            f"{str(path)!r} holds {X.shape} windows; the card says {card.n_train} of "
            f"({w.n_channels}, {w.n_samples})."
        )
    return WindowSet(
        card.task,
        card.sensor,
        X,
        y if not card.class_names else y.astype(str),
        w,
        tuple(card.class_names),
        groups,
        rods,
        card.data,
        card.data_hash,
        tuple(card.excluded),
        card.profile,
        sessions,
        card.anchor,
    )


def recipe_of(card: ModelCard, seed: int = 0) -> Recipe:
    """The recipe that trained a bundle (its features, model, channels, feature bin and taper)."""
    fp = card.feature_params
    return Recipe(
        features=card.features,
        model=card.model,
        channels=fp.get("channels"),
        feature_bin_ns=fp.get("bin_ns"),
        bin_kernel=fp.get("bin_kernel", "box") if "bin_ns" in fp else None,
        taper=float(fp.get("taper", 0.0)),  # cards from before the taper: none
        rate_hz=card.rate_hz if card.sensor == "biotac" else None,
        anytime_post_ns=tuple(round(p * MS) for p in card.anytime_post_ms),
        seed=seed,
    )


def with_calibration(base: WindowSet, calib: WindowSet, weight: int) -> WindowSet:
    """``base`` and ``calib`` pooled, each calibration window repeated ``weight`` (>= 1) times.

    PerceptionError: windows of another task, sensor or geometry.
    """
    if weight < 1:
        raise PerceptionError(f"The 'weight' parameter must be >= 1. Got {weight} instead.")
    for what in ("task", "sensor", "geometry"):
        if getattr(calib, what) != getattr(base, what):
            raise PerceptionError(
                f"The calibration windows have {what} {getattr(calib, what)!r}; the bundle's "
                f"are {getattr(base, what)!r}. Cut them with the bundle's anchor and profile."
            )
    idx = np.repeat(np.arange(len(calib.y)), weight)
    rep = calib.subset(idx)
    offset = int(np.max(base.groups)) + 1 if len(base.groups) else 0
    names = tuple(sorted(set(base.class_names) | set(calib.class_names)))
    if not base.is_regression:
        y = np.concatenate([base.y, rep.y])
        few = [c for c in names if np.count_nonzero(y == c) < 2]
        if few:
            raise PerceptionError(
                f"Classes {few} would have a single window; the probability calibration needs 2 "
                "of each. Give 2 trials of them, or a 'weight' of at least 2."
            )
    return base._replace(
        X=np.concatenate([base.X, rep.X]),
        y=np.concatenate([base.y, rep.y]),
        class_names=names if not base.is_regression else (),
        groups=np.concatenate([base.groups, rep.groups + offset]),
        rod_length_m=np.concatenate([base.rod_length_m, rep.rod_length_m]),
        sessions=np.concatenate([base.session_of, rep.session_of]),
        source=f"{base.source} + {calib.source}",
        data_hash=f"{base.data_hash}+{calib.data_hash}",
    )


def calibrate(
    bundle: str | Path, calib: Session, out: str | Path, weight: int = DEFAULT_WEIGHT, seed: int = 0
) -> ModelCard:
    """The card (``calibration``, ``label_set`` set) of ``bundle`` adapted to ``calib``'s session.

    Each calibration trial is repeated ``weight`` times in the refit; the bundle goes to ``out``.
    PerceptionError: a bundle without its training windows, or windows that do not fit it.
    """
    card = read_card(bundle)
    if card.anchor and calib.windows.anchor and calib.windows.anchor != card.anchor:
        raise PerceptionError(
            f"The bundle's windows are anchored at {card.anchor!r}, the calibration session's at "
            f"{calib.windows.anchor!r}: load it with --anchor {card.anchor}."
        )
    ws = with_calibration(training_windows(bundle, card), calib.windows, weight)
    trained, anytime = fit_recipe(ws, recipe_of(card, seed))
    record: dict[str, Any] = {
        "session": calib.info.name,
        "date": calib.info.date,
        "data": calib.path,
        "n_trials": len(calib.windows.y),
        "weight": int(weight),
        "base_model": card.id,
    }
    if not calib.windows.is_regression:
        counts = np.unique(calib.windows.y.astype(str), return_counts=True)
        record["trials_per_class"] = {str(k): int(v) for k, v in zip(*counts, strict=True)}
    labels = calib.info.labels or calib.windows.class_names
    new = dataclasses.replace(
        trained.card,
        label_set=tuple(c for c in labels if c in trained.card.class_names),
        calibration=record,
        id="",  # a new id, made from the fields above
    )
    save_bundle(trained._replace(card=new), out, anytime, windows=ws)
    return new


def pick_trials(ws: WindowSet, per_class: int, rng: np.random.Generator) -> np.ndarray:
    """A boolean mask of ``per_class`` random windows of each class (all of a smaller class)."""
    mask = np.zeros(len(ws.y), dtype=bool)
    for c in ws.class_names:
        idx = np.flatnonzero(ws.y == c)
        mask[rng.choice(idx, size=min(per_class, len(idx)), replace=False)] = True
    return mask


def calibration_curve(
    sessions: list[Session],
    recipe: Recipe | None = None,
    trials: tuple[int, ...] = (0, 1, 2, 3),
    draws: int = 5,
    weight: int = DEFAULT_WEIGHT,
    seed: int = 0,
) -> dict[str, Any]:
    """Leave-one-session-out accuracy after calibrating with 0, 1, 2, 3 trials per class.

    Each held-out session gets ``draws`` random draws of that many trials per class added to the
    other sessions' windows, and is scored on its other windows of the shared classes, restricted
    to its label set (zero trials: the zero-shot score). Returns ``{"trials", "sessions": {name:
    [mean per trials]}, "mean"}`` and the settings, JSON-ready.
    """
    recipe = dataclasses.replace(recipe or Recipe(), anytime_post_ns=())
    rng = np.random.default_rng(seed)
    per_session: dict[str, list[float]] = {}
    for i, held in enumerate(sessions):
        others = without_single_windows(pooled([s for j, s in enumerate(sessions) if j != i]))[0]
        test = held.windows
        common = set(test.class_names) & set(others.class_names)
        if not common or len(others.class_names) < 2:
            continue
        labels = tuple(held.info.labels or test.class_names)
        row = []
        for n in trials:
            values = []
            for _ in range(draws if n else 1):
                picked = pick_trials(test, n, rng) if n else np.zeros(len(test.y), bool)
                train = with_calibration(others, test.subset(picked), weight) if n else others
                rest = test.subset(~picked & np.isin(test.y, sorted(common)))
                score = fit_and_score(train, rest, labels, recipe)["restricted"]
                values.append(score["value"])
            row.append(float(np.mean(values)))
        per_session[held.info.name] = row
    mean = np.mean(list(per_session.values()), axis=0) if per_session else []
    return {
        "trials": list(trials),
        "draws": draws,
        "weight": weight,
        "sessions": per_session,
        "mean": [float(v) for v in mean],
    }
