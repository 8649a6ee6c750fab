"""The graph's core on a bag, without ROS: what ``ext-sense replay BAG --offline`` runs.

The bag's packets go through the window stage and the model the nodes run, in log-time order:
two runs give identical estimates, and a packet bag gives those of the live run that recorded it.
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:  # heavy: imported by the functions, so ``ext-sense --help`` stays fast
    from ext_sense_perception.online.predictor import ModelBundle
    from ext_sense_perception.online.window import WindowConfig


def bag_task_sensor(path: Path) -> tuple[str, str]:
    """Task and sensor of a bag: its ``custom_data``, else its topics and first truth (BagError)."""
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


def packet_topic(topics: Mapping[str, Any], path: Path, sensor: str) -> str:
    """The bag's topic of ``sensor``'s packets (BagError: none, e.g. a bag to migrate)."""
    from ext_sense.topics import SENSOR_PACKETS
    from ext_sense_bags import BagError

    topic = SENSOR_PACKETS[sensor]
    if topic not in topics or not topics[topic].count:
        raise BagError(
            f"{path} holds no {topic}: a bag of decoded arrays from before packets is "
            f"migrated first (ext-sense bag migrate {path} OUT)."
        )
    return topic


def offline_estimates(
    bag_path: Path, config: WindowConfig, model: ModelBundle, from_seq: int = 0
) -> Iterator[tuple[str, Any]]:
    """Run the graph's core on a bag: yields ``(kind, item)``, kind estimate, truth or rejected.

    For food the truth stamps are the motion starts. ``from_seq`` replays as a consumer that
    joined at that packet; after the last one, pending windows close as at a stream's end.
    """
    from ext_sense_bags import BagReader
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
        stream = packet_topic(bag.topics, bag_path, sensor)
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
