"""``ext-sense biotac decode|encode``: bridge streams to JSON lines and back."""

from __future__ import annotations

import argparse
import sys

_CHUNK = 1 << 20


def register_biotac(subparsers: argparse._SubParsersAction) -> argparse.ArgumentParser:
    """Add the ``biotac`` subcommand with ``decode`` and ``encode``; return its parser."""
    parser = subparsers.add_parser(
        "biotac",
        help="BioTac bridge streams: decode to JSON lines, encode from them",
        description="Decode or encode the ext_sense BioTac bridge byte stream "
        "(docs/biotac_bridge.md).",
    )
    sub = parser.add_subparsers(dest="biotac_command", metavar="ACTION")
    sub.required = True

    dec = sub.add_parser(
        "decode",
        help="bridge stream -> one JSON object per CRC-valid frame",
        description="Decode a recorded bridge stream. One JSON object per frame that passed its "
        "CRC (keys sensor_id, seq, pac, electrodes, pdc, tac, tdc, parity_errors; null where a "
        "word failed parity or was an error reply); a one-line counter summary on stderr.",
    )
    dec.add_argument("stream", metavar="STREAM", help="recorded bytes ('-' for stdin)")
    dec.add_argument("--out", metavar="FRAMES.jsonl", default="-", help="output (default stdout)")
    dec.set_defaults(func=_decode)

    enc = sub.add_parser(
        "encode",
        help="JSON lines of frame values -> bridge stream",
        description="Write a bridge stream from JSON lines shaped like 'decode' output (seq may be "
        "omitted: it counts per sensor; null values are sent as words failing parity). A "
        "malformed line (not UTF-8, not JSON, a missing key, a value of the wrong type or out of "
        "range) stops it with one line naming the file and line number, exit code 2, and no "
        "output file.",
    )
    enc.add_argument("values", metavar="VALUES.jsonl", help="input ('-' for stdin)")
    enc.add_argument("--out", metavar="STREAM", required=True, help="output bytes ('-' for stdout)")
    enc.set_defaults(func=_encode)
    return parser


def _decode(args: argparse.Namespace) -> int:
    import json

    from ext_sense_drivers.biotac.decoder import BridgeDecoder
    from ext_sense_drivers.biotac.jsonl import frames_to_records

    try:
        src = sys.stdin.buffer if args.stream == "-" else open(args.stream, "rb")  # noqa: SIM115
    except OSError as err:
        print(f"ext-sense biotac decode: cannot read {args.stream!r}: {err}", file=sys.stderr)
        return 2
    try:
        out = sys.stdout if args.out == "-" else open(args.out, "w", encoding="utf-8")  # noqa: SIM115
    except OSError as err:
        src.close()
        print(f"ext-sense biotac decode: cannot write --out {args.out!r}: {err}", file=sys.stderr)
        return 2
    decoder = BridgeDecoder()
    try:
        while True:
            chunk = src.read(_CHUNK)
            frames = decoder.feed(chunk) if chunk else decoder.flush()
            for record in frames_to_records(frames):
                out.write(json.dumps(record, separators=(",", ":")) + "\n")
            if not chunk:
                break
    finally:
        if src is not sys.stdin.buffer:
            src.close()
        if out is not sys.stdout:
            out.close()
        else:
            out.flush()
    print(f"biotac decode: {decoder.counters.summary()}", file=sys.stderr)
    return 0


def _encode(args: argparse.Namespace) -> int:
    import contextlib
    import os

    from ext_sense_drivers.biotac.errors import BioTacError
    from ext_sense_drivers.biotac.jsonl import parse_line, record_to_frame

    name = "<stdin>" if args.values == "-" else args.values
    try:
        src = sys.stdin.buffer if args.values == "-" else open(args.values, "rb")  # noqa: SIM115
    except OSError as err:
        print(f"ext-sense biotac encode: cannot read {args.values!r}: {err}", file=sys.stderr)
        return 2
    try:
        out = sys.stdout.buffer if args.out == "-" else open(args.out, "wb")  # noqa: SIM115
    except OSError as err:
        print(f"ext-sense biotac encode: cannot write --out {args.out!r}: {err}", file=sys.stderr)
        return 2
    next_seq = [0] * 5
    n = lineno = 0
    error = ""
    try:
        for lineno, raw in enumerate(src, start=1):
            if not raw.strip():
                continue
            where = f"{name}, line {lineno}"
            out.write(record_to_frame(parse_line(raw, where), next_seq, where=where))
            n += 1
        out.flush()
    except BioTacError as err:
        error = str(err)
    except OSError as err:  # reading the input or writing the output failed
        error = f"{name}, near line {max(lineno, 1)}: {err}"
    finally:
        if src is not sys.stdin.buffer:
            src.close()
        if out is not sys.stdout.buffer:
            with contextlib.suppress(OSError):
                out.close()
    if error:
        if out is not sys.stdout.buffer and os.path.isfile(args.out):
            os.unlink(args.out)  # no half-written stream left behind
        print(f"ext-sense biotac encode: {error}", file=sys.stderr)
        return 2
    print(f"biotac encode: frames={n}", file=sys.stderr)
    return 0
