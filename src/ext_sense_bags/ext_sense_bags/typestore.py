"""A rosbags typestore holding the ROS 2 standard types plus the ``ext_sense_msgs`` messages.

The ext_sense types are parsed from the ``.msg`` files rosidl builds, so the RIHS01 hashes in
bags equal the built interfaces'. The files are looked up in ``$EXT_SENSE_MSGS_DIR``, the source
tree, the ament index, then ``<sys.prefix>/share/ext_sense_msgs/msg``.
"""

from __future__ import annotations

import os
import sys
from functools import lru_cache
from pathlib import Path

from rosbags.typesys import Stores, get_types_from_msg, get_typestore
from rosbags.typesys.store import Typestore

from ext_sense_bags.errors import BagError

EXT_SENSE_TYPES: tuple[str, ...] = (
    "ext_sense_msgs/msg/BioTacFrame",
    "ext_sense_msgs/msg/ContactEstimate",
    "ext_sense_msgs/msg/ContactGroundTruth",
    "ext_sense_msgs/msg/ContactWindow",
    "ext_sense_msgs/msg/SensorPacket",
    "ext_sense_msgs/msg/TaxelEventBatch",
)
"""Every message type of ``ext_sense_msgs``."""

STORES = {"kilted": Stores.ROS2_KILTED, "jazzy": Stores.ROS2_JAZZY}
"""Distribution name -> the rosbags store its standard types come from."""


def msg_dir() -> Path:
    """The first directory holding the ``ext_sense_msgs`` ``.msg`` files (module docstring).

    Raises:
        BagError: None does.
    """
    candidates: list[Path] = []
    if env := os.environ.get("EXT_SENSE_MSGS_DIR"):
        candidates.append(Path(env))
    candidates.append(Path(__file__).resolve().parents[2] / "ext_sense_msgs" / "msg")
    try:
        from ament_index_python.packages import get_package_share_directory

        candidates.append(Path(get_package_share_directory("ext_sense_msgs")) / "msg")
    except Exception:  # ament index absent or package not installed
        pass
    candidates.append(Path(sys.prefix) / "share" / "ext_sense_msgs" / "msg")
    for path in candidates:
        if all((path / f"{t.rsplit('/', 1)[1]}.msg").is_file() for t in EXT_SENSE_TYPES):
            return path
    tried = ", ".join(str(p) for p in candidates)
    raise BagError(f"ext_sense_msgs .msg files not found; expected them in one of: {tried}")


def make_typestore(distro: str = "kilted") -> Typestore:
    """The shared (cached) typestore of ``distro`` (kilted, jazzy) with the ext_sense messages.

    Do not register further types into it.

    Raises:
        BagError: Unknown distribution or missing ``.msg`` files.
    """
    return _typestore(distro)  # one cache key per distro, however the caller names it


@lru_cache(maxsize=4)
def _typestore(distro: str) -> Typestore:
    if distro not in STORES:
        raise BagError(f"The 'distro' parameter must be one of {sorted(STORES)}. Got {distro!r}.")
    store = get_typestore(STORES[distro])
    folder = msg_dir()
    types = {}
    for name in EXT_SENSE_TYPES:
        text = (folder / f"{name.rsplit('/', 1)[1]}.msg").read_text(encoding="utf-8")
        types.update(get_types_from_msg(text, name))
    store.register(types)
    return store


def type_hash(msgtype: str, distro: str = "kilted") -> str:
    """RIHS01 hash of ``msgtype`` (``"RIHS01_<64 hex>"``), as rosidl computes it.

    Raises:
        BagError: ``msgtype`` is not in the typestore.
    """
    store = make_typestore(distro)
    if msgtype not in store.fielddefs:
        raise BagError(f"Unknown message type {msgtype!r}: not in the {distro} typestore.")
    return store.hash_rihs01(msgtype)
