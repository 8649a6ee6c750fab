"""Building rosbags message objects of any type in the typestore, with every field defaulted.

Fields left out get ROS defaults (0, ``""``, ``False``, empty or zero-filled arrays, nested
messages built the same way), so a caller names only what it knows. Primitive arrays are NumPy
arrays of the field's dtype. Helpers build the three messages a simulator writes.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from rosbags.interfaces import Nodetype

from ext_sense_bags.errors import BagError
from ext_sense_bags.typestore import make_typestore
from ext_sense_runtime.stamps import split_ns

_DTYPES: dict[str, type] = {
    "bool": np.bool_,
    "byte": np.uint8,
    "char": np.uint8,
    "int8": np.int8,
    "uint8": np.uint8,
    "int16": np.int16,
    "uint16": np.uint16,
    "int32": np.int32,
    "uint32": np.uint32,
    "int64": np.int64,
    "uint64": np.uint64,
    "float32": np.float32,
    "float64": np.float64,
}


def _default(desc: tuple[Any, Any], distro: str) -> Any:
    kind, detail = desc
    if kind == Nodetype.BASE:
        name = detail[0]
        if name == "string":
            return ""
        if name == "bool":
            return False
        if name.startswith("float"):
            return 0.0
        return 0
    if kind == Nodetype.NAME:
        return make_message(detail, distro=distro)
    sub, count = detail
    if sub[0] == Nodetype.BASE and sub[1][0] in _DTYPES:
        return np.zeros(count if kind == Nodetype.ARRAY else 0, dtype=_DTYPES[sub[1][0]])
    if kind == Nodetype.ARRAY:
        return [_default(sub, distro) for _ in range(count)]
    return []


def make_message(msgtype: str, distro: str = "kilted", **fields: Any) -> Any:
    """Build a message object of ``msgtype`` with the given fields and defaults for the rest.

    Args:
        msgtype: Full type name, e.g. ``"ext_sense_msgs/msg/TaxelEventBatch"``.
        distro: Typestore distribution (see :func:`ext_sense_bags.typestore.make_typestore`).
        **fields: Field values; primitive arrays are converted to NumPy arrays of the
            field's dtype.

    Returns:
        The rosbags dataclass instance, ready for :meth:`ext_sense_bags.BagWriter.write`.

    Raises:
        BagError: Unknown type or field name, or an array of the wrong fixed length.
    """
    store = make_typestore(distro)
    if msgtype not in store.fielddefs:
        raise BagError(f"Unknown message type {msgtype!r}: not in the {distro} typestore.")
    _, fielddefs = store.fielddefs[msgtype]
    known = {name for name, _ in fielddefs}
    if unknown := set(fields) - known:
        raise BagError(
            f"{msgtype} has no field(s) {sorted(unknown)}; its fields are {sorted(known)}."
        )
    values = {}
    for name, desc in fielddefs:
        if name not in fields:
            values[name] = _default(desc, distro)
            continue
        value = fields[name]
        kind, detail = desc
        if kind in (Nodetype.ARRAY, Nodetype.SEQUENCE) and detail[0][0] == Nodetype.BASE:
            dtype = _DTYPES.get(detail[0][1][0])
            if dtype is not None:
                value = np.ascontiguousarray(value, dtype=dtype).reshape(-1)
                if kind == Nodetype.ARRAY and value.size != detail[1]:
                    raise BagError(
                        f"{msgtype}.{name} must hold exactly {detail[1]} values. "
                        f"Got {value.size} instead."
                    )
        values[name] = value
    return store.types[msgtype](**values)


def stamp(ns: int, distro: str = "kilted") -> Any:
    """Build a ``builtin_interfaces/msg/Time`` of integer nanoseconds."""
    sec, nanosec = split_ns(ns)
    return make_message("builtin_interfaces/msg/Time", distro, sec=sec, nanosec=nanosec)


def duration(ns: int, distro: str = "kilted") -> Any:
    """Build a ``builtin_interfaces/msg/Duration`` of integer nanoseconds."""
    sec, nanosec = split_ns(ns)
    return make_message("builtin_interfaces/msg/Duration", distro, sec=sec, nanosec=nanosec)


def header(stamp_ns: int, frame_id: str = "", distro: str = "kilted") -> Any:
    """Build a ``std_msgs/msg/Header`` stamped at ``stamp_ns`` (integer nanoseconds)."""
    return make_message(
        "std_msgs/msg/Header", distro, stamp=stamp(stamp_ns, distro), frame_id=frame_id
    )


def taxel_event_batch(
    stamp_ns: int,
    taxel: Any,
    polarity: Any,
    value: Any,
    offset_ns: Any,
    *,
    frame_id: str = "nuskin",
    words_total: int = 0,
    resyncs: int = 0,
    skipped_bytes: int = 0,
    bad_taxel_words: int = 0,
    flag: Any = None,
) -> Any:
    """Build a ``TaxelEventBatch`` from parallel arrays (see the .msg for units).

    ``flag`` is the receiver words' flag bit per event, as received (0/1); ``None`` leaves
    the message's ``flag`` empty: the source has no such bit (simulator datasets, the ACES
    line).

    Raises:
        BagError: The arrays differ in length, an offset is negative or a flag not 0/1.
    """
    arrays = [np.asarray(a) for a in (taxel, polarity, value, offset_ns)]
    flags = np.zeros(0, np.uint8) if flag is None else np.asarray(flag).ravel()
    if len({a.size for a in arrays}) != 1 or (flag is not None and flags.size != arrays[0].size):
        sizes = [a.size for a in arrays] + ([flags.size] if flag is not None else [])
        raise BagError(
            f"taxel, polarity, value, offset_ns (and flag) must have one length. Got {sizes}."
        )
    if arrays[3].size and int(arrays[3].min()) < 0:
        raise BagError("offset_ns must be >= 0 (times after header.stamp).")
    if flags.size and not np.isin(flags, (0, 1)).all():
        raise BagError(f"flag must be 0 or 1 per event. Got {sorted(set(flags.tolist()))}.")
    return make_message(
        "ext_sense_msgs/msg/TaxelEventBatch",
        header=header(stamp_ns, frame_id),
        taxel=arrays[0],
        polarity=arrays[1],
        value=arrays[2],
        offset_ns=arrays[3],
        words_total=words_total,
        resyncs=resyncs,
        skipped_bytes=skipped_bytes,
        bad_taxel_words=bad_taxel_words,
        flag=flags.astype(np.uint8),
    )


def biotac_frame(
    stamp_ns: int,
    pac: Any,
    electrodes: Any,
    pdc: int,
    tac: int,
    tdc: int,
    *,
    sensor_id: int = 0,
    sequence: int = 0,
    pac_sample_period_ns: int = 454_545,
    frame_id: str = "biotac",
    **counters: int,
) -> Any:
    """Build a ``BioTacFrame`` (22 PAC samples, 19 electrodes; counters by keyword)."""
    return make_message(
        "ext_sense_msgs/msg/BioTacFrame",
        header=header(stamp_ns, frame_id),
        sensor_id=sensor_id,
        sequence=sequence % 65536,
        pac_sample_period_ns=pac_sample_period_ns,
        pac=pac,
        electrodes=electrodes,
        pdc=pdc,
        tac=tac,
        tdc=tdc,
        **counters,
    )


def sensor_packet(packet: Any, frame_id: str = "", distro: str = "kilted") -> Any:
    """A ``SensorPacket`` as the driver node publishes it, from a driver's packet.

    The packet (``ext_sense_drivers.packets.Packet``) is read by its fields, so bags stay free
    of the drivers.
    """
    return make_message(
        "ext_sense_msgs/msg/SensorPacket",
        distro,
        header=header(packet.stamp_ns, frame_id, distro),
        seq=packet.seq,
        encoding=packet.encoding,
        encoding_options=packet.options,
        time_base=packet.time_base,
        connection=packet.connection,
        end_of_stream=packet.end_of_stream,
        read_end=np.asarray(packet.read_end, np.uint32),
        read_offset_ns=np.asarray(packet.read_offset_ns, np.int64),
        data=np.frombuffer(packet.data, np.uint8),
    )


def ground_truth(
    stamp_ns: int,
    task: str,
    trial: int,
    *,
    tap_position_m: float = float("nan"),
    rod_length_m: float = float("nan"),
    class_label: str = "",
    frame_id: str = "",
) -> Any:
    """Build a ``ContactGroundTruth`` stamped at the true onset."""
    return make_message(
        "ext_sense_msgs/msg/ContactGroundTruth",
        header=header(stamp_ns, frame_id),
        task=task,
        trial=trial,
        tap_position_m=float(tap_position_m),
        rod_length_m=float(rod_length_m),
        class_label=class_label,
    )
