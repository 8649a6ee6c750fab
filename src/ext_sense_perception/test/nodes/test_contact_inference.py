"""The inference node refuses a bad bundle with one error, keeps running, and loads a fixed one."""

from __future__ import annotations

import json
import shutil
import time
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("rclpy")

from rosutil import spinning, wait_for

pytestmark = pytest.mark.ros


@pytest.fixture(scope="module")
def good_bundle(tap_npz: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    from ext_sense_perception.data.sources import from_sim_dataset
    from ext_sense_perception.training.bundle_io import save_bundle
    from ext_sense_perception.training.fit import fit_model

    ws = from_sim_dataset(tap_npz)
    return save_bundle(fit_model(ws, "fft", "svm_linear"), tmp_path_factory.mktemp("good"))


def _window():
    from ext_sense_msgs.msg import ContactWindow
    from ext_sense_runtime.stamps import MS, fill_stamp

    msg = ContactWindow()
    fill_stamp(msg.header.stamp, time.time_ns() - 251 * MS)
    msg.task, msg.sensor = "tap_localization", "nuskin"
    msg.pre_onset_ns, msg.post_onset_ns, msg.sample_period_ns = 50 * MS, 250 * MS, MS
    msg.shape, msg.channels = [80, 300], list(range(1, 81))
    msg.data = np.zeros(80 * 300, dtype=np.float32)
    return msg


class _Probe:
    def __init__(self, context) -> None:
        from diagnostic_msgs.msg import DiagnosticArray
        from rclpy.node import Node

        from ext_sense_msgs.msg import ContactEstimate, ContactWindow
        from ext_sense_runtime.qos import DIAGNOSTICS_QOS, ESTIMATE_QOS, WINDOW_QOS

        self.node = Node("probe", context=context)
        self.windows = self.node.create_publisher(ContactWindow, "window", WINDOW_QOS)
        self.estimates: list = []
        self.statuses: list = []
        self.node.create_subscription(
            ContactEstimate, "contact_estimate", self.estimates.append, ESTIMATE_QOS
        )
        self.node.create_subscription(
            DiagnosticArray,
            "/diagnostics",
            lambda m: self.statuses.extend(s for s in m.status if s.name.endswith(": model")),
            DIAGNOSTICS_QOS,
        )


def test_a_bad_bundle_is_refused_and_a_fixed_one_loaded_without_a_restart(good_bundle, tmp_path):
    from rclpy.parameter import Parameter

    from ext_sense_perception.nodes.contact_inference import ContactInferenceNode

    model = tmp_path / "model"
    shutil.copytree(good_bundle, model)
    card_file = model / "model_card.json"
    good_card = card_file.read_text()
    bad_card = json.loads(good_card)
    bad_card["class_names"] = ["near", "far"]  # on a regression model
    card_file.write_text(json.dumps(bad_card))
    probes: list[_Probe] = []

    def probe(context):
        probes.append(_Probe(context))
        return probes[-1].node

    params = [Parameter("model_path", value=str(model)), Parameter("reload_period_s", value=0.2)]
    with spinning(
        lambda context: ContactInferenceNode(context=context, parameter_overrides=params), probe
    ) as (node, _):
        p = probes[0]
        assert node.model is None
        assert "'class_names' must be empty: tap_localization is a regression task" in (
            node.model_error
        )
        assert "\n" not in node.model_error
        assert wait_for(lambda: any(s.level == b"\x02" for s in p.statuses), 5.0)
        assert "model refused: " in p.statuses[-1].message
        time.sleep(0.3)  # discovery
        p.windows.publish(_window())
        assert wait_for(lambda: node.dropped_no_model == 1, 10.0)  # alive, counting
        card_file.write_text(good_card)  # fixed: the retry loads it
        assert wait_for(lambda: node.model is not None, 10.0)
        p.windows.publish(_window())
        assert wait_for(lambda: len(p.estimates) == 1, 10.0)
        assert np.isfinite(p.estimates[0].tap_position_m)
        # the bundle rewritten for another sensor: seen as a change, refused
        bad_card = json.loads(good_card)
        bad_card["sensor"] = bad_card["window"]["sensor"] = "biotac"
        card_file.write_text(json.dumps(bad_card))
        assert wait_for(lambda: node.model is None, 10.0)
        assert node.reloads == 1
        assert "'window.period_ns' must be the profile's 454545" in node.model_error
        assert node.guard.total == 0


def _node_with(model: Path, probes: list, **extra):
    from rclpy.parameter import Parameter

    from ext_sense_perception.nodes.contact_inference import ContactInferenceNode

    params = [Parameter("model_path", value=str(model)), Parameter("reload_period_s", value=0.2)]
    params += [Parameter(k, value=v) for k, v in extra.items()]

    def probe(context):
        probes.append(_Probe(context))
        return probes[-1].node

    return spinning(
        lambda context: ContactInferenceNode(context=context, parameter_overrides=params), probe
    )


def test_a_vanished_model_directory_keeps_the_loaded_model_serving_until_a_valid_one_appears(
    good_bundle, tmp_path
):
    model = tmp_path / "model"
    shutil.copytree(good_bundle, model)
    probes: list[_Probe] = []
    with _node_with(model, probes) as (node, _):
        p = probes[0]
        assert node.model is not None
        loaded = node.model_id
        time.sleep(0.3)  # discovery
        shutil.rmtree(model)  # deleted while the graph runs
        assert wait_for(lambda: node.serving_vanished, 5.0)
        assert node.model is not None
        assert node.model_id == loaded
        assert wait_for(lambda: any(s.level == b"\x01" for s in p.statuses), 5.0)
        warn = next(s for s in p.statuses if s.level == b"\x01")
        p.windows.publish(_window())
        assert wait_for(lambda: len(p.estimates) == 1, 10.0)  # still served
        assert node.dropped_no_model == 0
        time.sleep(0.5)  # several retries: still serving, said once
        assert node.serving_vanished
        shutil.copytree(good_bundle, model)  # a valid bundle again: loaded
        assert wait_for(lambda: not node.serving_vanished, 5.0)
        assert node.model is not None
        assert node.guard.total == 0
    assert warn.message.startswith("model files gone: serving the loaded model")
    assert {kv.key: kv.value for kv in warn.values}["serving_vanished_model"] == "True"
    assert np.isfinite(p.estimates[0].tap_position_m)


def test_a_model_trained_on_another_rod_is_refused_and_an_old_card_accepted_with_a_warning(
    good_bundle, tmp_path
):
    model = tmp_path / "model"
    shutil.copytree(good_bundle, model)
    probes: list[_Probe] = []
    with _node_with(model, probes, held_object="rod:0.20") as (node, _):
        assert node.model is None  # trained on the dataset's 30 cm rod
        assert node.model_error.startswith(f"The model in {model} does not fit this graph: it ")
        assert "trained on a 30 cm rod, and the graph holds a 20 cm rod" in node.model_error
    with _node_with(model, probes, held_object="rod:0.30") as (node, _):
        assert node.model is not None
        assert node.object_note == ""
    card_file = model / "model_card.json"
    card = json.loads(card_file.read_text())
    del card["held_object"]  # a card written before cards recorded the object
    card_file.write_text(json.dumps(card))
    with _node_with(model, probes, held_object="rod:0.20") as (node, _):
        assert node.model is not None
        assert node.object_note.startswith("the model card records no held object")
