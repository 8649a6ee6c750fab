"""The model a graph will load, found and checked before any of its nodes starts.

A model of another task, sensor or held object (a 20 cm rod's places every tap on the 30 cm
scene wrong) is refused with one line naming what was searched and what to run.
"""

from __future__ import annotations

from collections.abc import Mapping

from ext_sense.graph import GraphError, GraphSpec
from ext_sense_perception.errors import PerceptionError
from ext_sense_perception.online.model_card import HeldObject, object_mismatch, read_card
from ext_sense_perception.online.model_store import create_command, create_hint, find_model
from ext_sense_sim.errors import SceneError
from ext_sense_sim.scene import DEFAULT_SCENES, load_scene

INFERENCE_EXECUTABLE = "contact_inference"


class ModelMissingError(GraphError):
    """The graph has no usable model: none found, an unreadable card, or another task's."""


def with_model(graph: GraphSpec, overrides: Mapping[str, str]) -> dict[str, str]:
    """``overrides`` with ``model`` set to the absolute bundle directory the graph will load.

    ``held_object`` is set too when named, recorded by the card, or a tap's rod. Raises
    GraphError (bad arguments) or ModelMissingError (no usable model).
    """
    values = graph.resolve(overrides)
    inference = [n for n in graph.build(values) if n.executable == INFERENCE_EXECUTABLE]
    if not inference:
        return dict(overrides)
    params = inference[0].parameters
    task, sensor = str(params["task"]), str(params["sensor"])
    try:
        path = find_model(values["model"], task, sensor)
        card = read_card(path)
    except PerceptionError as err:
        raise ModelMissingError(_one_line(str(err), sensor)) from err
    if (card.task, card.sensor) != (task, sensor):
        raise ModelMissingError(
            f"The model in {path} is for {card.task}/{card.sensor}; graph {graph.name!r} "
            f"with sensor:={sensor} needs a {task}/{sensor} model. To fix: "
            f"{create_hint(sensor)}, or give model:=DIR."
        )
    held = held_object_of_graph(values, task, sensor)
    why = object_mismatch(card.held_object, held)
    if why:
        raise ModelMissingError(
            f"The model in {path} does not fit graph {graph.name!r}: {why}. To fix: give "
            "model:=DIR of a model trained on this object, or held_object:=KIND:LENGTH_M "
            "naming what the fingers hold."
        )
    out = {**overrides, "model": str(path)}
    named = bool(values.get("held_object", "").strip())
    if held is not None and (named or card.held_object or task == "tap_localization"):
        out["held_object"] = held.to_text()
    return out


def held_object_of_graph(values: Mapping[str, str], task: str, sensor: str) -> HeldObject | None:
    """The graph's ``held_object``, else the simulator scene's (GraphError: unreadable)."""
    try:
        named = HeldObject.parse(values.get("held_object", ""))
    except PerceptionError as err:
        raise GraphError(f"The 'held_object' argument: {err}") from err
    if named is not None or values.get("source") != "sim":
        return named
    try:
        geometry = load_scene(values.get("scene") or DEFAULT_SCENES[(task, sensor)]).geometry
    except SceneError as err:
        raise GraphError(f"The 'scene' argument: {err}") from err
    return HeldObject(geometry.kind, round(geometry.length_m, 4))


def _one_line(message: str, sensor: str) -> str:
    """The lookup's message, with the command that creates models named once."""
    message = " ".join(message.split())
    if create_command(sensor) in message:
        return message
    return f"{message} To fix: {create_hint(sensor)}, or give model:=DIR."
