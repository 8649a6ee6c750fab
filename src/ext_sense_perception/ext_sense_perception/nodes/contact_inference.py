"""``contact_inference`` node: contact windows in, contact estimates out.

Subscribes ``window`` and publishes each contact's final estimate on ``contact_estimate``, its
anytime ones on ``contact_estimate/provisional`` (``publish_provisional``). Faults never stop the
node: a bundle missing, corrupt, for another task, sensor or ``held_object``, or unlike its card is
refused (ERROR, windows dropped) and retried every ``reload_period_s``; changed files are loaded
again; vanished files leave the loaded model served with a WARN. An estimate is ``degraded`` when
its window was, or when it is ready more than ``deadline_ms`` after the window ended (host clock;
a replayed bag's windows from their arrival).
"""

from __future__ import annotations

import array
import time
from collections import deque
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from rclpy.node import Node

from ext_sense_msgs.msg import ContactEstimate, ContactWindow
from ext_sense_perception.errors import PerceptionError
from ext_sense_perception.online.messages import window_from_msg
from ext_sense_perception.online.model_card import (
    CARD_FILE,
    ONNX_FILE,
    SKLEARN_FILE,
    HeldObject,
    object_mismatch,
    object_unknown,
)
from ext_sense_perception.online.model_store import default_name, locate_model
from ext_sense_perception.online.predictor import ModelBundle, load_model
from ext_sense_runtime import intra_process
from ext_sense_runtime.callback_guard import CallbackGuard
from ext_sense_runtime.diagnostics import Level, Updater
from ext_sense_runtime.diagnostics_ros import DiagnosticsPublisher
from ext_sense_runtime.node_main import run_node
from ext_sense_runtime.parameters import declare_all, param
from ext_sense_runtime.qos import ESTIMATE_QOS, WINDOW_QOS
from ext_sense_runtime.qos_events import QosEventCounter
from ext_sense_runtime.records import Estimate
from ext_sense_runtime.stamps import MS, fill_stamp

LIVE_CLOCK_TOLERANCE_NS = 10_000 * MS
"""A window ending further than this from the host clock is not live (replayed bag)."""


@dataclass(frozen=True)
class InferenceParameters:
    """``contact_inference``'s parameters; publish_provisional and deadline_ms change live."""

    task: str = param("tap_localization", "Task of the model.", read_only=True)
    sensor: str = param("nuskin", "Sensor of the model.", read_only=True)
    backend: str = param(
        "onnx", "Inference backend: onnx or sklearn.", read_only=True, choices=("onnx", "sklearn")
    )
    model_path: str = param(
        "",
        "Model bundle directory, or a model name looked up in $EXT_SENSE_MODELS, the user's "
        "data directory, the package share and the checkout's build/models; empty: the "
        "task's default model, <task>_<sensor>.",
        read_only=True,
    )
    publish_provisional: bool = param(
        True, "Publish estimates of provisional (anytime) windows on contact_estimate/provisional."
    )
    held_object: str = param(
        "",
        "The object the fingers hold, kind or kind:length_m (e.g. rod:0.30): a model "
        "whose card records another is refused; empty: not checked.",
        read_only=True,
    )
    reload_period_s: float = param(
        2.0,
        "Retry loading a missing or corrupt model this often, s.",
        low=0.1,
        high=3600.0,
        read_only=True,
    )
    deadline_ms: float = param(
        500.0,
        "An estimate ready later than this after its window ended is degraded, ms "
        "(live windows; a replayed bag's are measured from their arrival).",
        low=1.0,
        high=600000.0,
    )


class ContactInferenceNode(Node):
    """Runs a trained model on every contact window."""

    PARAMETERS = InferenceParameters

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(kwargs.pop("node_name", "contact_inference"), **kwargs)
        self.guard = CallbackGuard(self.get_logger().error)
        p = declare_all(self, InferenceParameters, self._on_change)
        self.task, self.sensor, self.backend = p.task, p.sensor, p.backend
        self.model_arg = p.model_path
        self.model_path: Path | None = None
        self._on_change(p)
        try:
            self.held_object = HeldObject.parse(p.held_object)
        except PerceptionError as err:
            raise ValueError(f"The 'held_object' parameter: {err}") from err
        self.model: ModelBundle | None = None
        self._stamp: tuple[tuple[str, int, int], ...] = ()
        self.reloads = 0
        self.model_id = ""
        self.model_error = ""
        self.serving_vanished = False
        """The bundle's files are gone: the model loaded before is served until a valid one
        appears (WARN); a bundle rewritten with bad files is refused instead."""
        self.object_note = ""
        self.windows_in = 0
        self.estimates_out = 0
        self.dropped_no_model = 0
        self.dropped_bad_window = 0
        self.degraded_out = 0
        self.last_degraded: tuple[int, str] | None = None
        self.last_window_error = ""
        self.last_reject_ns: int | None = None
        self.latencies_ns: deque[int] = deque(maxlen=500)

        self.qos_events = QosEventCounter()
        self.pub = self.create_publisher(
            ContactEstimate,
            "contact_estimate",
            ESTIMATE_QOS,
            event_callbacks=self.qos_events.publisher(),
        )
        self.provisional_pub = self.create_publisher(
            ContactEstimate,
            "contact_estimate/provisional",
            ESTIMATE_QOS,
            event_callbacks=self.qos_events.publisher(),
        )
        self.window_subscription = intra_process.create_subscription(
            self,
            ContactWindow,
            "window",
            self.guard(self._on_window),
            WINDOW_QOS,
            event_callbacks=self.qos_events.subscription(),
        )
        self.updater = Updater(hardware_id=self.model_arg or default_name(self.task, self.sensor))
        self.updater.add_check("model", self._check_model)
        self.updater.add_check("inference", self._check_inference)
        self.guard.attach(self.updater)
        self.diagnostics = DiagnosticsPublisher(self, self.updater)
        self._load()
        self.create_timer(p.reload_period_s, self.guard(self._retry_load))

    def _on_change(self, new: InferenceParameters) -> None:
        self.publish_provisional = new.publish_provisional
        self.deadline_ns = round(new.deadline_ms * MS)

    def _load(self) -> None:
        try:
            # a name is looked up again at every try: a model created meanwhile is found
            self.model_path = locate_model(self.model_arg, self.task, self.sensor)
            self._stamp = bundle_stamp(self.model_path, self.backend)
            model = load_model(self.model_path, self.backend, self.task, self.sensor)
            trained = getattr(model.card, "held_object", None)
            why = object_mismatch(trained, self.held_object)
            if why:
                raise PerceptionError(
                    f"The model in {self.model_path} does not fit this graph: {why}. To fix: "
                    "give a model trained on this object, or the object held (held_object)."
                )
        except PerceptionError as err:
            if self.model is not None and bundle_gone(self.model_path, self.backend):
                self._keep_serving(err)
                return
            if str(err) != self.model_error:
                self.get_logger().error(f"model refused: {err}")
            # the reason first: whoever sees no model (a test's thread) finds why
            self.model_error = str(err)
            self.model, self.model_id, self.serving_vanished = None, "", False
            return
        self.model, self.model_id = model, model.model_id
        self.model_error, self.serving_vanished = "", False
        self.get_logger().info(f"model {self.model_id or self.model_path} loaded ({self.backend})")
        self.object_note = object_unknown(trained, self.held_object)
        if self.object_note:
            self.get_logger().warning(f"model {self.model_id}: {self.object_note}")

    def _keep_serving(self, err: PerceptionError) -> None:
        """The loaded model's files are gone: serve it on, said once (WARN), until new ones load."""
        self.model_error = str(err)
        if self.serving_vanished:
            return
        self.serving_vanished = True
        self.get_logger().warning(
            f"model files in {self.model_path} are gone: serving the loaded model "
            f"{self.model_id} until a valid one appears ({err})"
        )
        self.diagnostics.publish()

    def _retry_load(self) -> None:
        if self.model is None or self.serving_vanished:
            self._load()
        elif self.model_path is not None and (
            bundle_stamp(self.model_path, self.backend) != self._stamp
        ):
            self.get_logger().info(f"model files in {self.model_path} changed: loading again")
            self.reloads += 1
            self._load()

    def _on_window(self, msg: ContactWindow) -> None:
        arrived = time.time_ns()
        self.windows_in += 1
        if self.model is None:
            self.dropped_no_model += 1
            return
        try:
            window = window_from_msg(msg)
            if window.provisional and not self.publish_provisional:
                return
            estimate = self.model.predict(window)
            now = time.time_ns()
            end = window.onset_ns + window.post_onset_ns
            live = abs(now - end) < LIVE_CLOCK_TOLERANCE_NS and now >= end
            latency = now - end if live else now - arrived
            reasons = [window.degraded_reason or "degraded window"] if window.degraded else []
            if latency > self.deadline_ns:
                reasons.append(
                    f"late: ready {latency / MS:.0f} ms after the window ended (deadline "
                    f"{self.deadline_ns / MS:.0f} ms)"
                )
            estimate = estimate._replace(
                compute_latency_ns=latency,
                degraded=bool(reasons),
                degraded_reason="; ".join(reasons),
            )
        except PerceptionError as err:
            self.dropped_bad_window += 1
            self.last_reject_ns = time.monotonic_ns()
            if str(err) != self.last_window_error:
                self.get_logger().warning(f"window dropped: {err}")
            self.last_window_error = str(err)
            return
        (self.provisional_pub if estimate.provisional else self.pub).publish(estimate_msg(estimate))
        self.estimates_out += 1
        if estimate.degraded:
            self.degraded_out += 1
            self.last_degraded = (time.monotonic_ns(), estimate.degraded_reason)
        if not estimate.provisional:
            self.latencies_ns.append(latency)

    def _check_model(self) -> tuple[Level, str, dict[str, object]]:
        trained = getattr(self.model.card, "held_object", None) if self.model else None
        values = {
            "model_path": str(self.model_path or self.model_arg),
            "backend": self.backend,
            "model_id": self.model_id,
            "reloads": self.reloads,
            "held_object": self.held_object.to_text() if self.held_object else "",
            "trained_held_object": trained.to_text() if trained else "",
            "serving_vanished_model": self.serving_vanished,
        }
        if self.model is None:
            return Level.ERROR, f"model refused: {self.model_error}", values
        if self.serving_vanished:
            return (
                Level.WARN,
                f"model files gone: serving the loaded model until a valid one appears "
                f"({self.model_error})",
                values,
            )
        if self.object_note:
            return Level.OK, f"loaded; {self.object_note}", values
        return Level.OK, "loaded", values

    def _check_inference(self) -> tuple[Level, str, dict[str, object]]:
        lat = np.asarray(self.latencies_ns, dtype=np.float64) / MS
        values: dict[str, object] = {
            "windows_in": self.windows_in,
            "estimates_out": self.estimates_out,
            "dropped_no_model": self.dropped_no_model,
            "dropped_bad_window": self.dropped_bad_window,
            "latency_p50_ms": f"{np.percentile(lat, 50):.3f}" if lat.size else "nan",
            "latency_p99_ms": f"{np.percentile(lat, 99):.3f}" if lat.size else "nan",
            "last_error": self.last_window_error,
            **self.qos_events.as_values(),
            **intra_process.delivery_values(self.window_subscription, "windows"),
            "estimates_degraded": self.degraded_out,
        }
        recent = self.last_reject_ns is not None and (
            time.monotonic_ns() - self.last_reject_ns < 10_000 * MS
        )
        if recent:
            return Level.WARN, f"windows rejected: {self.last_window_error}", values
        if self.last_degraded and time.monotonic_ns() - self.last_degraded[0] < 10_000 * MS:
            return Level.WARN, f"degraded estimates: {self.last_degraded[1]}", values
        return Level.OK, "ok", values


def bundle_gone(directory: Path | None, backend: str) -> bool:
    """Whether a bundle's card or the backend's model file is missing (deleted, not corrupt)."""
    if directory is None:
        return True
    model = ONNX_FILE if backend == "onnx" else SKLEARN_FILE
    return not all((Path(directory) / name).is_file() for name in (CARD_FILE, model))


def bundle_stamp(directory: Path, backend: str) -> tuple[tuple[str, int, int], ...]:
    """Name, mtime and size of the card and the backend's model file: changes when rewritten."""
    out = []
    for name in (CARD_FILE, ONNX_FILE if backend == "onnx" else SKLEARN_FILE):
        try:
            st = (Path(directory) / name).stat()
        except OSError:
            continue
        out.append((name, st.st_mtime_ns, st.st_size))
    return tuple(out)


def estimate_msg(est: Estimate) -> ContactEstimate:
    """The ``ContactEstimate`` message of an estimate."""
    msg = ContactEstimate()
    fill_stamp(msg.header.stamp, est.onset_ns)
    msg.header.frame_id = est.sensor
    msg.task, msg.sensor, msg.model_id = est.task, est.sensor, est.model_id
    msg.provisional = est.provisional
    fill_stamp(msg.post_contact_used, est.post_contact_used_ns)
    fill_stamp(msg.compute_latency, est.compute_latency_ns)
    msg.tap_position_m = est.tap_position_m
    msg.tap_position_std_m = est.tap_position_std_m
    msg.class_index = est.class_index
    msg.class_label = est.class_label
    msg.class_names = list(est.class_names)
    msg.class_probabilities = array.array("d", est.class_probabilities)
    msg.stability_probability = est.stability_probability
    msg.degraded, msg.degraded_reason = est.degraded, est.degraded_reason
    return msg


def main(args: list[str] | None = None) -> int:
    """Run the node (``ros2 run ext_sense_perception contact_inference``)."""
    return run_node(ContactInferenceNode, args)
