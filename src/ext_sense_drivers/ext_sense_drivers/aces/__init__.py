"""The ACES line: every taxel's event sends its 127-chip code on one shared line (docs/aces.md)."""

from ext_sense_drivers.aces.bank import (
    BANK_SPECS,
    DEFAULT_VERSION,
    CorrelationStats,
    SignatureBank,
    correlation_stats,
    load_bank,
)
from ext_sense_drivers.aces.decoder import LineDecoder, decode_line
from ext_sense_drivers.aces.encoder import EncodedLine, encode_line
from ext_sense_drivers.aces.enums import DecodeMode
from ext_sense_drivers.aces.errors import AcesError
from ext_sense_drivers.aces.line_counters import LineCounters
from ext_sense_drivers.aces.sample_clock import ns_to_sample, sample_to_ns
from ext_sense_drivers.aces.wire import COUNTS_PER_UNIT, bytes_to_samples, samples_to_bytes

__all__ = [
    "BANK_SPECS",
    "COUNTS_PER_UNIT",
    "DEFAULT_VERSION",
    "AcesError",
    "CorrelationStats",
    "DecodeMode",
    "EncodedLine",
    "LineCounters",
    "LineDecoder",
    "SignatureBank",
    "bytes_to_samples",
    "correlation_stats",
    "decode_line",
    "encode_line",
    "load_bank",
    "ns_to_sample",
    "sample_to_ns",
    "samples_to_bytes",
]
