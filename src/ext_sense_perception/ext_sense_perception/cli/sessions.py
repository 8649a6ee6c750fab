"""``ext-sense score|calibrate`` and ``evaluate --protocol cross-session``: models across days.

Handlers import lazily, as :mod:`.learning`'s, so ``ext-sense --help`` stays fast.
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import TYPE_CHECKING, Any

from ext_sense_perception.cli.options import add_data_options, fail, load_sessions, write_json
from ext_sense_perception.errors import PerceptionError

if TYPE_CHECKING:
    from ext_sense_perception.data.sessions import Session
    from ext_sense_perception.training.recipe import Recipe


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add ``score`` and ``calibrate``."""
    p = subparsers.add_parser(
        "score", help="score a trained bundle on new sessions (accuracy or MAE, calibration)"
    )
    p.add_argument("bundle", help="model bundle directory or model name")
    add_data_options(p)
    p.add_argument(
        "--labels",
        default=None,
        help="comma-separated label set decisions are restricted to (default: each session's "
        "own, from its session.json or its data; 'all': the model's classes)",
    )
    p.add_argument("--json", default=None, help="write the result as JSON here")
    p.set_defaults(func=_cmd_score)

    p = subparsers.add_parser(
        "calibrate",
        help="adapt a bundle to a new session from a few labelled trials of it (1-3 per class)",
    )
    p.add_argument("bundle", help="model bundle directory or model name")
    add_data_options(p)
    p.add_argument("--out", required=True, help="the calibrated bundle's directory")
    p.add_argument(
        "--weight",
        type=int,
        default=None,
        help="repeats of each calibration trial in the refit (default 2, measured)",
    )
    p.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    p.set_defaults(func=_cmd_calibrate)


def _bundle_path(args: argparse.Namespace) -> Path:
    """The ``BUNDLE`` argument: a bundle directory as given, else a model name looked up."""
    from ext_sense_perception.online.model_store import find_model

    given = Path(args.bundle).expanduser()
    if given.is_dir():  # a directory named on the command line, relative to where it is run
        return given.absolute()
    return find_model(args.bundle, args.task or "food_identification", args.sensor or "nuskin")


def _bundle_sessions(args: argparse.Namespace, path: Path, card: Any) -> list[Session]:
    """The ``--data`` sessions cut as the bundle's windows were (its task, sensor, anchor).

    PerceptionError: ``--task``/``--sensor`` or the data name another kind than the bundle's.
    """
    from ext_sense_perception.cli.options import Wanted

    anchor = card.anchor if card.task == "food_identification" else ""
    wanted = Wanted(card.task, card.sensor, anchor, f"the bundle {str(path)!r}")
    return load_sessions(args, wanted=wanted)


def _cmd_score(args: argparse.Namespace) -> int:
    import numpy as np

    from ext_sense_perception.data.sessions import pooled
    from ext_sense_perception.online.predictor import load_model
    from ext_sense_perception.training.scoring import score_classes, score_positions

    try:
        path = _bundle_path(args)
        model = load_model(path)
        sessions = _bundle_sessions(args, path, model.card)
        ws = pooled(sessions)
        rows = np.stack([model.prepare(x) for x in ws.X]) if len(ws.X) else np.zeros((0, 0))
        pred, proba = model.raw_predict(rows) if len(rows) else (np.zeros(0), None)
        if model.card.is_regression:
            result = score_positions(ws.y, pred, model.position_std_m)
        else:
            labels = _label_set(args.labels, sessions, model.card)
            names = [f"{s}/{g}" for s, g in zip(ws.session_of, ws.groups, strict=True)]
            if proba is None:
                proba = np.zeros((0, len(model.class_names)))
            result = score_classes(ws.y, proba, model.class_names, labels, names)
    except PerceptionError as err:
        return fail(err)
    result = {
        "task": model.card.task,
        "model_id": model.card.id,
        "bundle": str(path),
        "sessions": [s.info.name for s in sessions],
        **result,
    }
    _print_score(result)
    write_json(args.json, result)
    return 0


def _label_set(text: str | None, sessions: list[Session], card: Any) -> tuple[str, ...]:
    """``--labels``, else the sessions' declared (or observed) label sets, else the card's."""
    if text is not None:
        return (
            ()
            if text.strip().lower() == "all"
            else tuple(v.strip() for v in text.split(",") if v.strip())
        )
    declared = {c for s in sessions for c in (s.info.labels or s.windows.class_names)}
    return tuple(c for c in card.class_names if c in declared) or tuple(card.label_set)


def _print_score(r: dict[str, Any]) -> None:
    if r["metric"] == "mae_m":
        cal = r["calibration"]
        print(
            f"{r['task']} {r['model_id']}: mae {r['value'] * 100:.2f} cm over {r['n_windows']} "
            f"windows; 95% interval +-{cal['halfwidth_m'] * 100:.2f} cm covers "
            f"{cal['coverage']}"
        )
        return
    print(
        f"{r['task']} {r['model_id']}: accuracy {r['value']:.3f} over {r['n_windows']} windows"
        + (f" (decisions among {', '.join(r['label_set'])})" if r["label_set"] else "")
    )
    print("confusion (rows true, columns predicted):", ", ".join(r["class_names"]))
    for name, row in zip(r["class_names"], r["confusion"], strict=True):
        if sum(row):
            print(f"  {name:>12s} {row}")
    print(
        "expected calibration error "
        f"{r['calibration']['expected_calibration_error']:.3f} (mean confidence "
        f"{r['calibration']['mean_confidence']:.3f})"
    )
    if r["unknown"]:
        labels = sorted({u["label"] for u in r["unknown"]})
        print(
            f"{len(r['unknown'])} windows of classes the model does not know ({', '.join(labels)}),"
            " not scored"
        )


def _cmd_calibrate(args: argparse.Namespace) -> int:
    from ext_sense_perception.data.sessions import Session, SessionInfo, pooled
    from ext_sense_perception.online.model_card import read_card
    from ext_sense_perception.training.calibration import DEFAULT_WEIGHT, calibrate

    try:
        path = _bundle_path(args)
        card = read_card(path)
        sessions = _bundle_sessions(args, path, card)
        if len(sessions) == 1:
            calib = sessions[0]
        else:
            infos = [s.info for s in sessions]
            labels = tuple(sorted({c for i in infos for c in i.labels}))
            info = SessionInfo(name="+".join(i.name for i in infos), labels=labels)
            calib = Session(info, ",".join(args.data), pooled(sessions))
        weight = DEFAULT_WEIGHT if args.weight is None else args.weight
        new = calibrate(path, calib, args.out, weight=weight, seed=args.seed)
    except PerceptionError as err:
        return fail(err)
    per_class = new.calibration.get("trials_per_class")
    trials = (
        ", ".join(f"{k} {v}" for k, v in per_class.items())
        if per_class
        else f"{new.calibration['n_trials']} trials"
    )
    among = f"; decisions among {', '.join(new.label_set)}" if new.label_set else ""
    print(
        f"{args.out}: {new.id} calibrated to session {calib.info.name!r} ({trials}; weight "
        f"{weight}){among}"
    )
    return 0


def cross_session_command(args: argparse.Namespace, recipe: Recipe) -> int:
    """``ext-sense evaluate --protocol cross-session``: the table, and the JSON with ``--json``."""
    from ext_sense_perception.training.calibration import DEFAULT_WEIGHT, calibration_curve
    from ext_sense_perception.training.cross_session import cross_session

    try:
        sessions = load_sessions(args)
        result = cross_session(sessions, recipe)
        if args.calibration_trials:
            trials = _int_list(args.calibration_trials, "--calibration-trials")
            weight = DEFAULT_WEIGHT if args.weight is None else args.weight
            result["calibration_curve"] = calibration_curve(
                sessions, recipe, trials, args.draws, weight, args.seed
            )
    except PerceptionError as err:
        return fail(err)
    metric = result["metric"]
    print(
        f"{result['task']} {result['sensor']}, cross-session ({metric}), anchor "
        f"{result['anchor'] or 'source'}:"
    )
    print(
        f"  {'held-out session':<32s} {'date':<10s} {'n':>4s} {'value':>7s} {'unrestricted':>12s}"
    )
    for row in result["sessions"]:
        if "value" not in row:
            print(f"  {row['session']:<32s} {row['date']:<10s} skipped: {row['skipped']}")
            continue
        print(
            f"  {row['session']:<32s} {row['date']:<10s} {row['n_windows']:>4d} "
            f"{row['value']:>7.3f} {row['value_unrestricted']:>12.3f}"
        )
    print(
        f"  mean over {result['n_scored']} sessions: {result['mean']:.3f} "
        f"(unrestricted {result['mean_unrestricted']:.3f})"
    )
    curve = result.get("calibration_curve")
    if curve:
        print(
            f"calibration curve (trials per class -> accuracy; {curve['draws']} draws, weight "
            f"{curve['weight']}):"
        )
        print(f"  {'held-out session':<32s} " + " ".join(f"{n:>6d}" for n in curve["trials"]))
        for name, row in curve["sessions"].items():
            print(f"  {name:<32s} " + " ".join(f"{v:>6.3f}" for v in row))
        print(f"  {'mean':<32s} " + " ".join(f"{v:>6.3f}" for v in curve["mean"]))
    write_json(args.json, result)
    return 0


def _int_list(text: str, option: str) -> tuple[int, ...]:
    try:
        values = tuple(int(v) for v in text.split(",") if v.strip())
    except ValueError as err:
        raise PerceptionError(
            f"The '{option}' option must list whole numbers. Got {text!r} instead."
        ) from err
    if not values or min(values) < 0:
        raise PerceptionError(f"The '{option}' option must list numbers >= 0. Got {text!r}.")
    return values
