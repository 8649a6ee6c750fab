"""``ext-sense nuskin decode`` (a receiver capture to event CSV) and ``ext-sense biotac ...``."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from ext_sense_drivers.biotac.cli import register_biotac
from ext_sense_drivers.nuskin.events_csv import CSV_HEADER

_READ_BYTES = 1 << 20


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``nuskin`` and ``biotac`` subcommands."""
    nuskin = subparsers.add_parser("nuskin", help="NUSkin receiver tools (decode captures)")
    sub = nuskin.add_subparsers(dest="nuskin_command", metavar="COMMAND")
    sub.required = True
    decode = sub.add_parser(
        "decode",
        help="decode a raw receiver capture into one CSV row per word",
        description="Decode receiver event words (4 bytes each, tagged in the top 3 bits) "
        f"into CSV rows '{CSV_HEADER}'; counters go to stderr.",
    )
    decode.add_argument("raw_file", type=Path, metavar="RAW_FILE")
    decode.add_argument(
        "--out", type=Path, default=None, metavar="EVENTS.csv", help="output CSV (default stdout)"
    )
    decode.add_argument(
        "--flag-polarity",
        choices=("ignore", "is_positive"),
        default="ignore",
        help="how the word's flag bit maps to polarity (default ignore: 0 for every event, "
        "as the real receivers leave the bit at 0); the bit itself is always written, as "
        "received, in the flag column",
    )
    decode.set_defaults(func=_decode)
    register_biotac(subparsers)


def _decode(args: argparse.Namespace) -> int:
    from ext_sense_drivers.nuskin.events_csv import write_rows
    from ext_sense_drivers.nuskin.wire import FlagPolarity, WordDecoder

    decoder = WordDecoder(FlagPolarity[args.flag_polarity.upper()])
    try:
        source = args.raw_file.open("rb")
    except OSError as err:
        print(
            f"ext-sense nuskin decode: cannot read {str(args.raw_file)!r}: {err}", file=sys.stderr
        )
        return 2
    try:
        out = sys.stdout if args.out is None else args.out.open("w", encoding="ascii", newline="")
    except OSError as err:
        source.close()
        print(f"ext-sense nuskin decode: cannot write {str(args.out)!r}: {err}", file=sys.stderr)
        return 2
    try:
        out.write(CSV_HEADER + "\n")
        n = 0
        while True:
            data = source.read(_READ_BYTES)
            if not data:
                break
            words = decoder.feed(data)
            n += write_rows(out, n, words.polarity, words.taxel, words.value, words.flag)
        decoder.flush()
    finally:
        source.close()
        if out is not sys.stdout:
            out.close()
    c = decoder.counters
    print(
        f"{args.raw_file.name}: bytes={c.bytes_in} words={c.words} resyncs={c.resyncs} "
        f"skipped_bytes={c.skipped_bytes} bad_taxel_words={c.bad_taxel_words}",
        file=sys.stderr,
    )
    return 0
