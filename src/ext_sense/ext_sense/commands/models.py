"""``ext-sense models create|list``: the default models of the three tasks, and where models are.

``create`` trains each task's default model for one sensor on the simulator into
``<task>_<sensor>/`` in the user's model store (or ``--out DIR``), checked writable first,
locked while made, each bundle renamed into place once complete; a model whose training inputs
are unchanged is kept (``--force`` retrains). ``list`` prints the search path and every bundle.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

TASKS = ("tap_localization", "handover_stability", "food_identification")


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``models`` subcommand with ``create`` and ``list``."""
    parser = subparsers.add_parser(
        "models",
        help="create the default models of the three tasks; list where models are found",
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    sub = parser.add_subparsers(dest="models_command", metavar="{create,list}")
    sub.required = True
    create = sub.add_parser(
        "create",
        help="train the default models on the simulator",
        description="Train the default model of each task on the scene simulator into "
        "OUT/<task>_<sensor>.",
    )
    create.add_argument(
        "--out",
        type=Path,
        help="directory of the bundles (default: $EXT_SENSE_MODELS when set, else "
        "$XDG_DATA_HOME/ext_sense/models, i.e. ~/.local/share/ext_sense/models)",
    )
    create.add_argument("--sensor", choices=("nuskin", "biotac"), default="nuskin")
    create.add_argument(
        "--task",
        action="append",
        choices=TASKS,
        help="only this task (repeatable; default: all three)",
    )
    create.add_argument(
        "--force", action="store_true", help="retrain even when a current model is there"
    )
    create.set_defaults(func=_create)
    listing = sub.add_parser("list", help="the search path and every model found along it")
    listing.set_defaults(func=_list)


def _log(line: str) -> None:
    print(f"[models] {line}", file=sys.stderr)


def _create(args: argparse.Namespace) -> int:
    from ext_sense_perception.errors import PerceptionError
    from ext_sense_perception.online.model_store import default_store
    from ext_sense_sim.default_models import create_models
    from ext_sense_sim.errors import SceneError

    out = (args.out or default_store()).expanduser().absolute()
    tasks = tuple(dict.fromkeys(args.task)) if args.task else TASKS
    try:
        create_models(out, args.sensor, tasks, args.force, _log)
    except (SceneError, PerceptionError) as err:
        print(f"ext-sense models: error: {err}", file=sys.stderr)
        return 2
    print(f"models of {', '.join(tasks)} ({args.sensor}) in {out}")
    return 0


def _list(args: argparse.Namespace) -> int:
    from ext_sense_perception.errors import PerceptionError
    from ext_sense_perception.online.model_card import read_card
    from ext_sense_perception.online.model_store import (
        describe,
        find_model,
        search_places,
        stored_models,
    )

    print("search path (a name is looked up in this order; never in the working directory):")
    for i, place in enumerate(search_places(), 1):
        absent = place.root is not None and not place.root.is_dir()
        print(f"  {i}. {describe(place)}{' (absent)' if absent else ''}")
    print("models:")
    found = stored_models()
    for m in found:
        try:
            card = read_card(m.path)
            what = f"{card.task}/{card.sensor} {card.id} {_metrics(card.metrics)}"
        except PerceptionError as err:
            what = f"unusable: {err}"
        shadow = " (shadowed by an earlier place)" if m.shadowed else ""
        print(f"  {m.name:<28} {m.place.label:<17} {m.path}{shadow}\n      {what}")
    if not found:
        print("  none")
    print("task defaults (what a graph loads without model:=):")
    for sensor in ("nuskin", "biotac"):
        for task in TASKS:
            try:
                where = str(find_model("", task, sensor))
            except PerceptionError:
                where = "not found"
            print(f"  {task + '/' + sensor:<28} -> {where}")
    return 0


def _metrics(metrics: dict[str, float]) -> str:
    shown = {k: v for k, v in metrics.items() if k in ("cv_mae_m", "cv_accuracy")}
    return " ".join(f"{k}={v:.4g}" for k, v in shown.items())
