"""The core of ``ext-sense collect`` without ROS: sequences, answers, state and resume."""

from __future__ import annotations

import pytest

from ext_sense.collect.graph import (
    COLLECTOR_NODE,
    SIM_TRIGGER_TOPIC,
    SIM_TRUTH_TOPIC,
    collect_nodes,
)
from ext_sense.collect.session import (
    HANDOVER_CLASSES,
    Answers,
    CollectError,
    CollectState,
    class_sequence,
    grasp_class,
    grasp_end,
    grasp_windows,
    match_truth,
    parse_class,
    parse_decision,
    sim_schedule,
    tap_sequence,
    window_note,
)
from ext_sense.graphs import GRAPHS, TOPIC_HANDOVER_OFFER
from ext_sense_runtime.stamps import S


def test_tap_sequence_covers_the_marked_range_shuffled():
    seq = tap_sequence(5, 0.05, 0.25, seed=1)
    assert sorted(seq) == [0.05, 0.1, 0.15, 0.2, 0.25]
    assert seq != sorted(seq) or tap_sequence(5, 0.05, 0.25, seed=2) != seq
    with pytest.raises(CollectError, match="low < high"):
        tap_sequence(3, 0.2, 0.1, seed=0)


def test_class_sequence_is_balanced():
    seq = class_sequence(["a", "b", "c"], 7, seed=3)
    assert sorted(seq.count(c) for c in "abc") == [2, 2, 3]


def test_parse_class_by_name_prefix_or_number():
    classes = ("water", "apple", "green_pepper")
    assert parse_class("Green pepper", classes) == "green_pepper"
    assert parse_class("2", classes) == "apple"
    assert parse_class("wa", classes) == "water"
    with pytest.raises(CollectError, match="must be one of"):
        parse_class("steak", classes)


def test_discard_brings_the_prompt_back_and_state_round_trips(tmp_path):
    st = CollectState("food_identification", ["water", "apple", "tofu"])
    st.keep("water", [1])
    st.keep("apple", [2])
    assert st.discard_last().label == "apple"
    assert st.prompt() == "apple"
    st.keep("apple", [3])
    st.save(tmp_path)
    again = CollectState.load(tmp_path)
    assert again == st
    assert again.progress() == "[2/3] apple=1 water=1"
    with pytest.raises(CollectError, match="Cannot resume"):
        CollectState.load(tmp_path / "nothing")


def test_sim_schedule_plays_the_named_foods_only():
    food = ("water", "apple")
    assert sim_schedule(
        "food_identification", ["water", "discard", "apple", "q", "water"], food
    ) == ["water", "apple"]
    # a handover grasp is played as the pending answer says when it is offered (grasp_class)
    assert sim_schedule("handover_stability", ["stable", "unstable"], HANDOVER_CLASSES) == []


def test_a_grasp_is_played_as_the_pending_answer_names_it():
    answers = Answers(["unst", "redo", "stable"])
    assert grasp_class(answers.peek(), HANDOVER_CLASSES) == "unstable"
    assert grasp_class(answers.peek(), HANDOVER_CLASSES) == "unstable"  # peeking takes nothing
    assert answers.ask("grasp?") == "unst"
    assert grasp_class(answers.peek(), HANDOVER_CLASSES) == ""  # a redone grasp: any class
    answers.ask("grasp?")
    assert grasp_class(answers.peek(), HANDOVER_CLASSES) == "stable"
    answers.ask("grasp?")
    assert answers.peek() is None
    assert answers.ask("grasp?") == "quit"  # a script that runs out ends the session
    assert grasp_class(None, HANDOVER_CLASSES) == ""
    assert Answers().peek() is None


def test_a_grasp_runs_from_its_offer_to_the_decision_that_ends_it():
    decisions = [
        parse_decision("[100] HOLDING: HOLD - handover started"),
        parse_decision("[150] HOLDING: HOLD - P(stable)=0.20 < 0.80"),
        parse_decision("[900] TIMED_OUT: HOLD - no stable grasp within 6.0 s"),
        parse_decision("[1000] HOLDING: HOLD - handover started"),
        parse_decision("[1400] RELEASED: NONE - the gripper reports open"),
    ]
    assert decisions[2] == (900, "TIMED_OUT")
    assert grasp_end(100, decisions) == 900
    assert grasp_end(1000, decisions) == 1400
    assert grasp_end(1500, decisions) is None  # not over yet
    windows = [90, 120, 120, 850, 901, 1100]
    assert grasp_windows(100, 900, windows) == [120, 850]
    assert grasp_windows(1000, 1400, windows) == [1100]
    assert grasp_windows(1500, 1600, windows) == []  # a grasp without a window
    with pytest.raises(CollectError, match="must read"):
        parse_decision("RELEASED without a stamp")


def test_window_note_only_when_the_model_window_outlasts_the_probe():
    assert window_note(3 * S, 4 * S) == ""
    note = window_note(8 * S, 4 * S)
    assert "8.0 s after the motion start, the probe 4.0 s" in note


def test_match_truth_within_tolerance_only():
    truths = [(100, "a"), (1_000, "b")]
    assert match_truth(950, truths, 100) == "b"
    assert match_truth(500, truths, 100) == ""


def test_collect_graph_moves_the_simulator_truth_and_stops_self_started_probes():
    values = GRAPHS["food_identification"].resolve({"behaviours": "true"})
    nodes = collect_nodes("food_identification", GRAPHS["food_identification"].build(values), True)
    assert all(s.executable != "estimate_monitor" for s in nodes)
    sim = next(s for s in nodes if s.executable == "sim_device")
    assert ("ground_truth", SIM_TRUTH_TOPIC) in sim.remappings
    assert sim.parameters["listener_node"] == COLLECTOR_NODE  # no trial before the bag hears
    assert sim.parameters["wait_for_listener_s"] > 0
    food = next(s for s in nodes if s.executable == "food_behaviour")
    assert food.parameters["auto_start"] is False
    assert food.parameters["repeat_s"] == 0.0


def test_scripted_handover_on_the_simulator_is_triggered_by_collect():
    graph = GRAPHS["handover"]
    built = graph.build(graph.resolve({"behaviours": "true"}))
    plain = collect_nodes("handover_stability", built, True)
    sim = next(s for s in plain if s.executable == "sim_device")
    assert ("trigger", TOPIC_HANDOVER_OFFER) in sim.remappings  # unscripted: the offer
    nodes = collect_nodes("handover_stability", built, True, sim_trigger=True)
    sim = next(s for s in nodes if s.executable == "sim_device")
    assert ("trigger", SIM_TRIGGER_TOPIC) in sim.remappings
    assert ("ground_truth", SIM_TRUTH_TOPIC) in sim.remappings
    behaviour = next(s for s in nodes if s.executable == "handover_behaviour")
    assert ("handover/offer", TOPIC_HANDOVER_OFFER) in behaviour.remappings
