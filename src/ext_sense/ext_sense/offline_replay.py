"""The graph's core on a bag, without ROS: what ``ext-sense replay BAG --offline`` runs.

Kept apart from the command (:mod:`ext_sense.commands.bags`) so that tests and tools drive the
same function: a bag's sensor stream goes through the window stage and the model the nodes run,
in log-time order, so two runs on one bag give identical estimates, and a bag of raw packets
gives the estimates of the live run that recorded it.
"""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:  # heavy: imported by the functions, so ``ext-sense --help`` stays fast
    from ext_sense_perception.online.predictor import ModelBundle
    from ext_sense_perception.online.window import WindowConfig


def bag_task_sensor(path: Path) -> tuple[str, str]:
    """Task and sensor of a bag: its ``custom_data`` (``task``, ``sensor``), else guessed.

    The guess takes the sensor from the stream topic present and the task from the first
    ground-truth message.

    Raises:
        BagError: Neither can be told.
    """
    from ext_sense_bags import BagError, BagReader

    with BagReader(path) as bag:
        custom = bag.custom_data
        topics = bag.topics
        task, sensor = custom.get("task", ""), custom.get("sensor", "")
        if not sensor:
            if {"/extsense/nuskin/packets", "/extsense/nuskin/events"} & set(topics):
                sensor = "nuskin"
            elif {"/extsense/biotac/packets", "/extsense/biotac/frames"} & set(topics):
                sensor = "biotac"
        if not task and "/extsense/ground_truth" in topics:
            for _, msg in bag.messages(["/extsense/ground_truth"]):
                task = str(msg.task)
                break
    if not task or not sensor:
        raise BagError(f"Cannot tell the task/sensor of {path}: give --task and --sensor.")
    return task, sensor


def offline_estimates(
    bag_path: Path, config: WindowConfig, model: ModelBundle, from_seq: int = 0
) -> Iterator[tuple[str, Any]]:
    """Run the graph's core on a bag: yields ``("estimate", Estimate)`` and ``("truth", msg)``.

    Sensor messages feed :class:`~ext_sense_perception.online.stage.WindowStage` in log-time
    order, cutting the windows of ``config`` (the model card's task profile, as the window node
    does); each window goes through ``model.predict``, as in the inference node. Compute
    latency is measured per window (feature + model time, no transport) and is the only field
    that differs between runs. For food the ground-truth stamps mark the motion start, as
    ``motion_start`` does in the graph.

    The driver's raw packets are decoded with the library decoder, as the live window node
    does (:meth:`WindowStage.on_packet`), and windows close by its one time rule: the same
    packets give the same windows as the live run that recorded them. ``from_seq`` replays as a
    consumer that joined the stream at that packet (the window node logs the first ``seq`` it
    saw). After the last packet, windows still pending are closed as the stream ending would.

    Raises:
        BagError: The bag holds no packets of the sensor (a bag of decoded arrays from before
            packets: ``ext-sense bag migrate``).
    """
    from ext_sense.topics import SENSOR_PACKETS
    from ext_sense_bags import BagError, BagReader
    from ext_sense_perception.errors import PerceptionError
    from ext_sense_perception.online.stage import WindowStage
    from ext_sense_runtime.stamps import stamp_to_ns

    stage = WindowStage(config)
    sensor = config.sensor.label

    def run(windows: list) -> Iterator[tuple[str, Any]]:
        for win in windows:
            try:
                estimate = model.predict(win)
            except PerceptionError as err:
                yield "rejected", str(err)
                continue
            yield "estimate", estimate

    with BagReader(bag_path) as bag:
        stream = SENSOR_PACKETS[sensor]
        packets = bag.topics.get(stream)
        if packets is None or not packets.count:
            raise BagError(
                f"{bag_path} holds no {stream}: a bag of decoded arrays from before packets is "
                f"migrated first (ext-sense bag migrate {bag_path} OUT)."
            )
        wanted = [t for t in (stream, "/extsense/ground_truth") if t in bag.topics]
        for rec, msg in bag.messages(wanted):
            if rec.topic == "/extsense/ground_truth":
                if config.external_onsets:
                    stage.on_motion_start(stamp_to_ns(msg.header.stamp))
                yield "truth", msg
                continue
            if int(msg.seq) < from_seq:
                continue
            yield from run(stage.on_packet(msg))
        if stage.last_data_ns is not None:
            yield from run(stage.advance(stage.last_data_ns + config.post_ns))
        yield from run(stage.flush())
