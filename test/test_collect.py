"""``ext-sense collect``: scripted sessions against the simulated devices, then trained on.

Each test runs the real graph (simulated device, driver, window and inference nodes, the task's
behaviours) and the real collect command with ``--answers``, then checks the collected bag:
every label the operator gave equals the simulator's own ground truth for that trial (recorded
apart on ``/extsense/sim/ground_truth``; handover: the class the simulator played in the grasp
the window lies in), redone trials are absent, ``session.json`` holds the session's metadata,
and ``ext-sense train --data BAG`` trains a bundle that loads (tap and handover). The food
session is interrupted (its script ends) and finished with ``--resume``: still one bag with
every label.
"""

from __future__ import annotations

import json
import math
import re
import subprocess
from pathlib import Path

import pytest
from sim_models import EXE, train_sim_model

from ext_sense_bags import BagReader
from ext_sense_runtime.stamps import stamp_to_ns

pytestmark = [pytest.mark.slow, pytest.mark.ros, pytest.mark.timeout(240)]


def _collect(out: Path, task: str, model: Path, answers: list[str], *extra: str) -> str:
    script = out.parent / f"{out.name}.answers"
    script.write_text("\n".join(answers) + "\n")
    proc = subprocess.run(
        [*EXE, "collect", task, str(out), "--answers", str(script), f"model:={model}", *extra],
        capture_output=True,
        text=True,
        timeout=150,
    )
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    return proc.stdout


def _truths(bag: Path, topic: str) -> list[tuple[int, int, str]]:
    """``(stamp_ns, trial, label)`` of every ground truth on ``topic``."""
    with BagReader(bag) as reader:
        return [
            (
                stamp_to_ns(m.header.stamp),
                int(m.trial),
                m.class_label or f"{m.tap_position_m:.3f}",
            )
            for _, m in reader.messages([topic])
        ]


def _nearest(stamp: int, truths: list[tuple[int, int, str]]) -> tuple[int, int, str]:
    return min(truths, key=lambda t: abs(t[0] - stamp))


def _trains(bag: Path, out: Path) -> None:
    from ext_sense_perception.online.predictor import load_model

    proc = subprocess.run(
        [*EXE, "train", "--data", str(bag), "--out", str(out)],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert proc.returncode == 0, proc.stdout[-2000:] + proc.stderr[-2000:]
    assert load_model(out, "sklearn").task


def _check_session(bag: Path, n: int, name_of_task: str) -> list[tuple[int, int, str]]:
    from ext_sense_perception.data.sessions import read_info

    info = read_info(bag)
    assert info is not None
    assert info.sensor == "nuskin"
    assert info.name == bag.name
    labels = _truths(bag, "/extsense/ground_truth")
    assert len({t for _, t, _ in labels}) == n, labels
    sim = _truths(bag, "/extsense/sim/ground_truth")
    assert sim, "the simulator's truth was not recorded"
    with BagReader(bag) as reader:
        assert reader.custom_data["task"] == name_of_task
        assert reader.topics["/extsense/nuskin/packets"].count > 0  # recorded by default
    return labels


def test_collect_tap_session_labels_are_the_simulated_taps(tmp_path):
    model, _ = train_sim_model(tmp_path, "tap_rod30_nuskin", "tap_localization", 40)
    bag = tmp_path / "tap_session"
    answers = ["keep", "redo"] + ["keep"] * 8 + ["discard"] + ["keep"] * 2
    out = _collect(bag, "tap_localization", model, answers, "--trials", "10")
    assert "[10/10]" in out, out[-2000:]
    labels = _check_session(bag, 10, "tap_localization")
    sim = _truths(bag, "/extsense/sim/ground_truth")
    for stamp, _, label in labels:
        sim_stamp, _, sim_label = _nearest(stamp, sim)
        assert abs(sim_stamp - stamp) < 150_000_000
        assert math.isclose(float(label), float(sim_label), abs_tol=1e-3), (label, sim_label)
    _trains(bag, tmp_path / "tap_bundle")


def test_collect_food_session_interrupted_resumed_labels_are_the_simulated_foods(tmp_path):
    """Four trials (five probes, one redone), not the eight a trained model needs: a food probe
    takes about 11 s, and the tap and handover sessions check that a collected bag trains (this
    test took 126 s of the suite's 12 min of graphs with eight trials, 89 s with five)."""
    model, _ = train_sim_model(tmp_path, "food_fork_nuskin", "food_identification", 14)
    bag = tmp_path / "food_session"
    foods = ["water", "apple", "tofu", "apple"]
    options = ("--trials", "4", "--classes", "water,apple,tofu")
    # the first script ends after three kept trials (one discarded and redone): the session
    # stops, resumable
    out = _collect(bag, "food_identification", model, [*foods[:3], "discard", foods[2]], *options)
    assert "[3/4]" in out, out[-2000:]
    assert "unfinished: continue with --resume" in out, out[-2000:]
    assert [t["label"] for t in json.loads((bag / "collect.json").read_text())["trials"]] == foods[
        :3
    ]
    out = _collect(bag, "food_identification", model, foods[3:], *options, "--resume")
    assert "[4/4]" in out, out[-2000:]
    # each probe shows its live estimate, or says why there is none
    shown = re.findall(r"probed \w+; estimate (.*)", out)
    assert len(shown) == 1, out[-2000:]
    assert all(e != "none" for e in shown), shown
    assert sorted(p.name for p in bag.iterdir()) == [
        "collect.json",
        "food_session.mcap",
        "metadata.yaml",
        "session.json",
    ]
    labels = _check_session(bag, 4, "food_identification")
    assert [label for _, _, label in labels] == foods
    sim = _truths(bag, "/extsense/sim/ground_truth")
    for stamp, _, label in labels:
        sim_stamp, _, sim_label = _nearest(stamp, sim)
        assert sim_stamp == stamp, (stamp, sim_stamp, labels, sim)
        assert sim_label == label, (label, sim_label)


def test_collect_handover_session_labels_are_the_simulated_grasps(tmp_path):
    model, _ = train_sim_model(tmp_path, "handover_rod_nuskin", "handover_stability", 20)
    bag = tmp_path / "handover_session"
    grasps = ["stable", "unstable", "unstable", "stable"]
    answers = [*grasps[:2], "redo", *grasps[2:]]
    out = _collect(bag, "handover_stability", model, answers, "--trials", "4")
    assert "[4/4]" in out, out[-2000:]
    labels = _check_session(bag, 4, "handover_stability")
    sim = _truths(bag, "/extsense/sim/ground_truth")
    offers = sorted(stamp for stamp, _, _ in _truths(bag, "/extsense/handover/offer"))
    assert len(offers) >= len(answers), offers  # every answer judged a grasp of its own
    # a grasp runs from its offer to the next; every window of it carries the grasp's label,
    # which is the class the simulator played in that grasp (all its trials, one class)
    by_trial: dict[int, set[int]] = {}
    for stamp, trial, label in labels:
        grasp = max(g for g, offer in enumerate(offers) if offer <= stamp)
        end = offers[grasp + 1] if grasp + 1 < len(offers) else math.inf
        played = {lab for t, _, lab in sim if offers[grasp] <= t < end}
        assert played == {label}, (trial, label, played)
        by_trial.setdefault(trial, set()).add(grasp)
    assert all(len(g) == 1 for g in by_trial.values()), by_trial  # a trial is one grasp
    order = [next(iter(by_trial[t])) for t in sorted(by_trial)]
    assert order == sorted(set(order)), order  # one grasp per trial, in the session's order
    kept = [next(lab for _, tr, lab in labels if tr == t) for t in sorted(by_trial)]
    assert kept == grasps
    _trains(bag, tmp_path / "handover_bundle")
