"""SynTouch BioTac over the ext_sense serial/CAN bridge: SPI reply words, bridge frames, timing.

Pure Python/NumPy (no rclpy): :mod:`.words` (reply word codec and the standard 44-word
sequence), :mod:`.crc` (CRC-16/CCITT-FALSE), :mod:`.frame_layout` (the bridge frame's bytes),
:mod:`.encoder` (frame encoders), :mod:`.decoder` (the vectorised streaming
:class:`~.decoder.BridgeDecoder`), :mod:`.frames` (decoded frame records), :mod:`.counters`
(sequence tracking and the decoders' counters), :mod:`.reference` (a plain per-byte decoder kept
as the reference for tests and the benchmark), :mod:`.clock` (integer-nanosecond sample times),
:mod:`.jsonl` (the JSON-lines form used by ``ext-sense biotac``), :mod:`.driver_config` (the
``biotac_driver`` node's settings) and :mod:`.cli`. The protocol is documented in
``docs/biotac_bridge.md``.
"""
