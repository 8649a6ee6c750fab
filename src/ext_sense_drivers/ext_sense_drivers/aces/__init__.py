"""The ACES line: every taxel's event sends its 127-chip code on one shared line (docs/aces.md)."""

from ext_sense_drivers.aces.bank import correlation_stats, load_bank
from ext_sense_drivers.aces.decoder import LineDecoder, decode_line
from ext_sense_drivers.aces.encoder import encode_line
from ext_sense_drivers.aces.enums import DecodeMode
from ext_sense_drivers.aces.errors import AcesError
from ext_sense_drivers.aces.sample_clock import ns_to_sample, sample_to_ns
from ext_sense_drivers.aces.wire import COUNTS_PER_UNIT, bytes_to_samples, samples_to_bytes

__all__ = [
    "COUNTS_PER_UNIT",
    "AcesError",
    "DecodeMode",
    "LineDecoder",
    "bytes_to_samples",
    "correlation_stats",
    "decode_line",
    "encode_line",
    "load_bank",
    "ns_to_sample",
    "sample_to_ns",
    "samples_to_bytes",
]
