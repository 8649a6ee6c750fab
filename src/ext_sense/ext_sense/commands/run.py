"""``ext-sense run GRAPH [name:=value ...]``: a node graph without ``ros2 launch``."""

from __future__ import annotations

import argparse
import sys

from ext_sense.graph import GraphError, parse_assignments
from ext_sense.graphs import GRAPHS


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``run`` subcommand."""
    graphs = "\n".join(f"  {name:<22}{g.description}" for name, g in GRAPHS.items())
    parser = subparsers.add_parser(
        "run",
        help="run a node graph (the same one the launch files start)",
        usage="ext-sense run [-h] [--in-process] [--show-args] [--dry-run] GRAPH [name:=value ...]",
        description="Run a node graph without ros2 launch, its processes as the launch files "
        "start them (hot_path:=processes: one per node).\n\n"
        f"graphs:\n{graphs}\n\n"
        "Arguments are given as name:=value, as with ros2 launch; "
        "--show-args lists a graph's arguments.",
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("graph", choices=sorted(GRAPHS), metavar="GRAPH")
    parser.add_argument(
        "--in-process", action="store_true", help="all nodes on one executor in this process"
    )
    parser.add_argument(
        "--show-args", action="store_true", help="list the graph's arguments and exit"
    )
    parser.add_argument(
        "--dry-run", action="store_true", help="print the nodes that would start and exit"
    )
    parser.set_defaults(func=_run, accepts_assignments=True)


def _run(args: argparse.Namespace) -> int:
    from ext_sense.graph_model import with_model

    graph = GRAPHS[args.graph]
    if args.show_args:
        for a in graph.arguments:
            kind = f" ({a.expected()})" if a.choices or a.kind is not str else ""
            print(f"{a.name}:={a.default!r}{kind}\n    {a.description}")
        return 0
    try:  # every argument typed and range-checked
        overrides = parse_assignments(args.assignments)
        nodes = graph.nodes(overrides)
    except GraphError as err:
        print(f"ext-sense run: {err}", file=sys.stderr)
        return 2
    if args.dry_run:
        try:  # show the bundle the graph would load; a missing one or file is only noted here
            graph.check_files(graph.resolve(overrides))
            nodes = graph.nodes(with_model(graph, overrides))
        except GraphError as err:
            print(f"note: {err}", file=sys.stderr)
        for spec in nodes:
            remaps = " ".join(f"{a}:={b}" for a, b in spec.remappings)
            params = " ".join(f"{k}:={v!r}" for k, v in spec.parameters.items())
            required = " (required)" if spec.required else ""
            print(f"{spec.name}: {spec.package}/{spec.executable}{required}")
            print(f"    parameters: {params}\n    remappings: {remaps}")
        return 0
    try:  # before any node starts: missing files, or no usable model, are refused here
        graph.check_files(graph.resolve(overrides))
        overrides = with_model(graph, overrides)
    except GraphError as err:
        print(f"ext-sense run: {err}", file=sys.stderr)
        return 2
    print(f"[run] model {overrides['model']}", file=sys.stderr)
    from ext_sense.runner import run_graph

    return run_graph(graph, overrides, in_process=args.in_process)
