"""Typestores built from the message definitions a bag recorded, for bags older than a type.

When a ``.msg`` file of ``ext_sense_msgs`` changes (a field added), the bytes of every bag
recorded before no longer fit the current typestore: deserializing them with it fails
(``unpack_from requires a buffer of at least ...``) and the recording is lost to training,
replay and plotting. rosbag2 stores, per topic, the RIHS01 hash of the type it recorded and
(mcap schema, sqlite3 ``message_definitions``) the full definition text with its
dependencies. :func:`decoding_store` compares the recorded hash with the current one and, when
they differ, returns a typestore built from the recorded text, so the bytes decode to a message
with the fields as recorded. One such store is built per ``(distro, type, hash)`` and shared.

:func:`to_current` turns a message of a recorded definition into one of the current type, the
fields the recording lacks at their defaults: what a live graph fed from an old bag needs.
"""

from __future__ import annotations

import threading
from typing import Any, NamedTuple

from rosbags.interfaces import MessageDefinitionFormat, Nodetype
from rosbags.typesys import get_types_from_idl, get_types_from_msg, get_typestore
from rosbags.typesys.store import Typestore

from ext_sense_bags.errors import BagError
from ext_sense_bags.messages import make_message
from ext_sense_bags.typestore import STORES, make_typestore

_IDL_SEP = "=" * 80 + "\n"
_ENCODINGS = {
    MessageDefinitionFormat.MSG: "ros2msg",
    MessageDefinitionFormat.IDL: "ros2idl",
    MessageDefinitionFormat.NONE: "",
}


class TypeSource(NamedTuple):
    """The typestore a connection's messages decode with, and why."""

    store: Typestore
    recorded: bool
    """True: built from the bag's own definition (it differs from the current one)."""
    problem: str
    """Why the bag's definition could not be used although its hash differs ('' when not)."""


_LOCK = threading.Lock()
_CACHE: dict[tuple[str, str, str], Typestore | str] = {}
"""``(distro, type, recorded hash or 'def:' + text)`` -> store, or why none could be built."""


def _types_of(msgtype: str, msgdef: str, encoding: str) -> dict[str, Any]:
    """Parse a stored definition (``ros2msg`` text with its dependencies, or ``ros2idl``)."""
    if encoding == "ros2idl":
        if msgdef.startswith(f"{_IDL_SEP}IDL: "):
            types: dict[str, Any] = {}
            for part in msgdef.split(_IDL_SEP)[1:]:
                types.update(get_types_from_idl(part.split("\n", 1)[1]))
            return types
        return dict(get_types_from_idl(msgdef))
    return dict(get_types_from_msg(msgdef, msgtype))


def _build(distro: str, msgtype: str, msgdef: str, encoding: str) -> Typestore | str:
    """A fresh distro store with the recorded types in place of any same-named ones.

    The distro's standard types stay for dependencies the text may leave out; a recorded type
    replaces the store's own, so an old ``std_msgs/Header`` (say) decodes as recorded too.
    """
    try:
        types = _types_of(msgtype, msgdef, encoding)
        if msgtype not in types:
            return f"its stored definition does not define {msgtype}"
        store = get_typestore(STORES[distro])
        for name in types:
            store.fielddefs.pop(name, None)
            store.types.pop(name, None)
        store.register(types)
        store.hash_rihs01(msgtype)  # every dependency resolves
    except Exception as err:  # rosbags' parser and type system raise several types
        return f"its stored definition does not parse: {err}"
    return store


def _recorded_store(
    distro: str, msgtype: str, type_hash: str, msgdef: str, encoding: str
) -> Typestore | str:
    key = (distro, msgtype, type_hash or f"def:{msgdef}")
    with _LOCK:
        if key not in _CACHE:
            _CACHE[key] = _build(distro, msgtype, msgdef, encoding)
        return _CACHE[key]


def decoding_store(
    msgtype: str,
    type_hash: str,
    msgdef: str,
    encoding: str | MessageDefinitionFormat = "ros2msg",
    distro: str = "kilted",
) -> TypeSource:
    """The typestore to decode a connection's messages with.

    Args:
        msgtype: The connection's type name.
        type_hash: RIHS01 hash the bag recorded for it ('' when none).
        msgdef: Definition text the bag recorded ('' when none).
        encoding: ``"ros2msg"``/``"ros2idl"`` (or rosbags' format enum).
        distro: Distribution of the current typestore.

    Returns:
        The current typestore when the recorded type is the current one (same hash), or when
        the bag holds no usable definition (``problem`` says why: decoding then fails with a
        clear error if the layouts differ); else one built from the recorded definition.
    """
    current = make_typestore(distro)
    known = msgtype in current.fielddefs
    now = current.hash_rihs01(msgtype) if known else ""
    if type_hash and type_hash == now:
        return TypeSource(current, False, "")
    encoding = _ENCODINGS.get(encoding, encoding) if not isinstance(encoding, str) else encoding
    if not msgdef or not encoding:
        why = "" if not type_hash or not known else "the bag stores no definition of it"
        return TypeSource(current, False, why)
    built = _recorded_store(distro, msgtype, type_hash, msgdef, encoding)
    if isinstance(built, str):
        return TypeSource(current, False, built)
    if known and built.hash_rihs01(msgtype) == now:  # a bag without hashes, current layout
        return TypeSource(current, False, "")
    return TypeSource(built, True, "")


def to_current(msg: Any, msgtype: str, distro: str = "kilted") -> Any:
    """``msg`` (of any definition of ``msgtype``) as a message of the current definition.

    Fields the current type has and ``msg`` lacks (added since the recording) get their ROS
    defaults; fields ``msg`` has and the current type lacks are dropped. Nested messages are
    converted the same way.

    Raises:
        BagError: ``msgtype`` is not in the current typestore, or a field does not convert.
    """
    store = make_typestore(distro)
    if msgtype not in store.fielddefs:
        raise BagError(f"Unknown message type {msgtype!r}: not in the {distro} typestore.")
    fields: dict[str, Any] = {}
    for name, (kind, detail) in store.fielddefs[msgtype][1]:
        if not hasattr(msg, name):
            continue
        value = getattr(msg, name)
        if kind == Nodetype.NAME:
            value = to_current(value, detail, distro)
        elif kind in (Nodetype.ARRAY, Nodetype.SEQUENCE) and detail[0][0] == Nodetype.NAME:
            value = [to_current(v, detail[0][1], distro) for v in value]
        fields[name] = value
    try:
        return make_message(msgtype, distro, **fields)
    except (TypeError, ValueError) as err:
        raise BagError(f"A recorded {msgtype} does not convert to the current type: {err}") from err
