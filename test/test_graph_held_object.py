"""A graph refuses a model trained on another object than the one it holds, before any node."""

from __future__ import annotations

import dataclasses
import subprocess
import sys
from pathlib import Path

import pytest
from sim_models import write_card

from ext_sense.graph_model import ModelMissingError, held_object_of_graph, with_model
from ext_sense.graphs import GRAPHS
from ext_sense_perception.online.model_card import HeldObject, read_card


def _rod_card(directory: Path, length_m: float | None) -> Path:
    """A tap card that records a rod of ``length_m`` (None: a card from before the field)."""
    write_card(directory, "tap_localization")
    card = read_card(directory)
    held = None if length_m is None else HeldObject("rod", length_m)
    dataclasses.replace(card, held_object=held, id="").write(directory)
    return directory


def test_a_20_cm_rod_model_on_the_30_cm_scene_is_refused_in_one_line(tmp_path):
    model = _rod_card(tmp_path / "rod20", 0.20)
    graph = GRAPHS["tap_localization"]
    with pytest.raises(ModelMissingError) as info:
        with_model(graph, {"model": str(model)})  # the default scene: tap_rod30_nuskin
    message = str(info.value)
    assert message.startswith(f"The model in {model} does not fit graph 'tap_localization': ")
    assert "it was trained on a 20 cm rod, and the graph holds a 30 cm rod" in message
    assert "\n" not in message
    # its own scene, or the rod named, and it is the model served (checked by the node too)
    ok = with_model(graph, {"model": str(model), "scene": "tap_rod20_nuskin"})
    assert (ok["model"], ok["held_object"]) == (str(model), "rod:0.2")
    assert with_model(graph, {"model": str(model), "held_object": "rod:0.2"})["model"]
    params = {n.name: n.parameters for n in graph.build(graph.resolve(ok))}
    assert params["contact_inference"]["held_object"] == "rod:0.2"


def test_a_card_without_an_object_is_accepted_and_a_sensor_graph_names_none_by_itself(tmp_path):
    old = _rod_card(tmp_path / "old", None)
    ok = with_model(GRAPHS["tap_localization"], {"model": str(old)})
    assert (ok["model"], ok["held_object"]) == (str(old), "rod:0.3")  # the node warns
    values = GRAPHS["food_identification"].resolve({})
    assert held_object_of_graph(values, "food_identification", "nuskin") == HeldObject("fork", 0.19)
    food = write_card(tmp_path / "food", "food_identification")  # records no object
    ok = with_model(GRAPHS["food_identification"], {"model": str(food)})
    assert "held_object" not in ok  # nothing to check: no warning either
    values = GRAPHS["tap_localization"].resolve({"source": "serial"})
    assert held_object_of_graph(values, "tap_localization", "nuskin") is None


def test_a_handover_model_of_the_rod_is_refused_on_the_box_scene(tmp_path):
    write_card(tmp_path / "handover", "handover_stability")
    card = read_card(tmp_path / "handover")
    dataclasses.replace(card, held_object=HeldObject("rod", 0.4), id="").write(
        tmp_path / "handover"
    )
    with pytest.raises(
        ModelMissingError, match=r"trained on a 40 cm rod, and the graph holds a 20"
    ):
        with_model(
            GRAPHS["handover"],
            {"model": str(tmp_path / "handover"), "scene": "handover_box_nuskin"},
        )


def test_a_malformed_held_object_argument_is_refused(tmp_path):
    from ext_sense.graph import GraphError

    model = _rod_card(tmp_path / "rod30", 0.30)
    with pytest.raises(GraphError, match=r"The 'held_object' argument: .*length must be"):
        with_model(GRAPHS["tap_localization"], {"model": str(model), "held_object": "rod:-3"})


def test_run_refuses_the_mismatched_model_before_any_node(tmp_path):
    model = _rod_card(tmp_path / "rod20", 0.20)
    out = subprocess.run(
        [sys.executable, "-m", "ext_sense.cli", "run", "tap_localization", f"model:={model}"],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert out.returncode == 2
    assert out.stderr.startswith("ext-sense run: The model in ")
    assert "trained on a 20 cm rod, and the graph holds a 30 cm rod" in out.stderr
    assert len(out.stderr.strip().splitlines()) == 1
