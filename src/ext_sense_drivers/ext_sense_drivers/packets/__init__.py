"""Raw sensor packets: the bytes a driver read, batched by time, and the one decoder library.

As the event-camera stacks do (``event_camera_msgs/EventPacket`` and its codecs), a driver
publishes what it read (``ext_sense_msgs/SensorPacket``: stamp, ``seq``, ``encoding``, the reads
and their arrival times) and never needs to decode; every consumer (the window node, the offline
replay, training from bags, the driver itself when asked for decoded arrays) decodes with
:func:`make_decoder`, so they all see the same events, and a bag of packets can be decoded
again by a fixed decoder. No rclpy here: messages are read duck-typed (rclpy or rosbags).
"""

from ext_sense_drivers.packets.decoders import (
    BioTacPacketDecoder,
    DecodedFrame,
    DecodedFrames,
    NuskinPacketDecoder,
    PacketDecoder,
    make_decoder,
)
from ext_sense_drivers.packets.errors import PacketError
from ext_sense_drivers.packets.packet import (
    ACES_LINE_V1,
    BIOTAC_BRIDGE_V1,
    ENCODINGS,
    NUSKIN_WORDS_V1,
    QUIET_PACKETS_PERIOD_S,
    Packet,
    PacketPacker,
    QuietSchedule,
    format_options,
    packet_of,
    parse_options,
)

__all__ = [
    "ACES_LINE_V1",
    "BIOTAC_BRIDGE_V1",
    "ENCODINGS",
    "NUSKIN_WORDS_V1",
    "QUIET_PACKETS_PERIOD_S",
    "BioTacPacketDecoder",
    "DecodedFrame",
    "DecodedFrames",
    "NuskinPacketDecoder",
    "Packet",
    "PacketDecoder",
    "PacketError",
    "PacketPacker",
    "QuietSchedule",
    "format_options",
    "make_decoder",
    "packet_of",
    "parse_options",
]
