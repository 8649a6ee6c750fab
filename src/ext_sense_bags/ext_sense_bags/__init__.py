"""Pure-Python rosbag2 I/O for ext_sense: typestore with the ext_sense messages, writer, reader.

No rclpy import anywhere in this package, so simulators and offline tools can write bags that
``ros2 bag play`` accepts on a machine without ROS. See :mod:`ext_sense_bags.writer` for the
writer API and :mod:`ext_sense_bags.reader` for the reader; :mod:`ext_sense_bags.recover`
rewrites a bag a killed recorder left (:mod:`ext_sense_bags.salvage` reads it).
"""

from ext_sense_bags.errors import BagError
from ext_sense_bags.messages import (
    biotac_frame,
    ground_truth,
    header,
    make_message,
    taxel_event_batch,
)
from ext_sense_bags.reader import BagReader, BagRecord, TopicSummary
from ext_sense_bags.recover import Recovery, recover_bag
from ext_sense_bags.topics import STANDARD_TOPICS, TopicSpec
from ext_sense_bags.typestore import EXT_SENSE_TYPES, make_typestore, type_hash
from ext_sense_bags.writer import BagWriter, Storage

__all__ = [
    "EXT_SENSE_TYPES",
    "STANDARD_TOPICS",
    "BagError",
    "BagReader",
    "BagRecord",
    "BagWriter",
    "Recovery",
    "Storage",
    "TopicSpec",
    "TopicSummary",
    "biotac_frame",
    "ground_truth",
    "header",
    "make_message",
    "make_typestore",
    "recover_bag",
    "taxel_event_batch",
    "type_hash",
]
