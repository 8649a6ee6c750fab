"""The model a graph will load, found before any of its nodes starts (both front ends).

``ext-sense run`` and the launch files call :func:`with_model` on the graph's arguments: the
``model`` argument (a bundle directory, a model name, or empty for the task's default) is looked
up along the model search path
(:mod:`ext_sense_perception.online.model_store`), its card is read and checked against the
graph's task and sensor, and the bundle's absolute directory is handed to both perception nodes,
so the window node and the inference node read the same bundle. A graph with no usable model
refuses to start with one line that lists every place searched and names the command that
creates the default models. Nothing here imports ``launch`` or ``rclpy``.
"""

from __future__ import annotations

from collections.abc import Mapping

from ext_sense.graph import GraphError, GraphSpec
from ext_sense_perception.errors import PerceptionError
from ext_sense_perception.online.model_card import read_card
from ext_sense_perception.online.model_store import create_command, create_hint, find_model

INFERENCE_EXECUTABLE = "contact_inference"


class ModelMissingError(GraphError):
    """The graph has no usable model: none found, an unreadable card, or another task's."""


def with_model(graph: GraphSpec, overrides: Mapping[str, str]) -> dict[str, str]:
    """``overrides`` with ``model`` set to the absolute bundle directory the graph will load.

    Raises:
        GraphError: Bad arguments.
        ModelMissingError: No usable model (one line: what was searched, what to run).
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
    return {**overrides, "model": str(path)}


def _one_line(message: str, sensor: str) -> str:
    """The lookup's message, with the command that creates models named once."""
    message = " ".join(message.split())
    if create_command(sensor) in message:
        return message
    return f"{message} To fix: {create_hint(sensor)}, or give model:=DIR."
