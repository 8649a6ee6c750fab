"""Raw sensor packets (``ext_sense_msgs/SensorPacket``) and the one decoder library.

As with ``event_camera_msgs``, drivers publish what they read and every consumer decodes with
:func:`make_decoder`, so all see the same events and old bags decode with fixed decoders.
No rclpy: messages are read duck-typed (rclpy or rosbags).
"""

from ext_sense_drivers.packets.decoders import (
    BioTacPacketDecoder,
    DecodedFrame,
    NuskinPacketDecoder,
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
    "NuskinPacketDecoder",
    "Packet",
    "PacketError",
    "PacketPacker",
    "QuietSchedule",
    "format_options",
    "make_decoder",
    "packet_of",
    "parse_options",
]
