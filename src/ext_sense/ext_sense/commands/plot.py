"""``ext-sense plot SOURCE``: PNGs of a bag or a capture folder that a person reads without ROS.

``overview.png`` (event rate per taxel over time, the contacts marked, rate per finger) and
``contact_NNN.png`` per contact (its events, onset and window, the estimate beside the truth).
Drawing lives in :mod:`ext_sense.view.figures`; this module only parses and reports.
"""

from __future__ import annotations

import argparse
from pathlib import Path


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add ``plot``."""
    p = subparsers.add_parser(
        "plot",
        help="draw a bag or a capture folder as PNGs (overview, one figure per contact)",
        description="Draw a rosbag2 bag (directory, .mcap or .db3) or a folder of real NUSkin "
        "captures (*_zero_*.tact) as PNGs: overview.png and contact_NNN.png.",
    )
    p.add_argument("source", type=Path, help="bag, or capture folder")
    p.add_argument(
        "--out", type=Path, default=None, help="output directory (default: plots_<source name>)"
    )
    p.add_argument(
        "--max-contacts", type=int, default=20, help="figures of the first N contacts (default 20)"
    )
    p.add_argument("--dpi", type=int, default=110, help="resolution of the PNGs (default 110)")
    p.set_defaults(func=_plot)


def _plot(args: argparse.Namespace) -> int:
    from ext_sense.view.errors import ViewError
    from ext_sense.view.figures import plot_session
    from ext_sense.view.sessions import load_session

    if args.max_contacts < 0 or args.dpi < 20:
        print("ext-sense plot: --max-contacts must be >= 0 and --dpi >= 20")
        return 2
    out = args.out or Path(f"plots_{args.source.resolve().name}")
    try:
        session = load_session(args.source)
    except ViewError as err:
        print(f"ext-sense plot: {err}")
        return 2
    written = plot_session(session, out, args.max_contacts, args.dpi)
    print(
        f"{session.name}: {session.task or 'unknown task'}, {session.sensor}, "
        f"{session.events.size} events, {len(session.contacts)} contacts"
    )
    for path in written:
        print(path)
    return 0
