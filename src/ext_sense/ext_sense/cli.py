"""The ``ext-sense`` command: one entry point, subcommands contributed by each package.

Each module in :data:`COMMAND_MODULES` has ``register(subparsers)``; every subcommand sets
``func(args) -> int``. Heavy imports happen inside the handlers, so ``--help`` is fast, and this
module imports only ``os`` and ``sys`` before :func:`main` runs: a Ctrl-C during an import above
``main``'s ``try`` would be a traceback.
"""

from __future__ import annotations

import os
import sys

TYPE_CHECKING = False  # typing.TYPE_CHECKING without importing typing (see above)
if TYPE_CHECKING:
    import argparse
    from collections.abc import Sequence
    from typing import NoReturn

COMMAND_MODULES: tuple[str, ...] = (
    "ext_sense.commands.run",  # run GRAPH
    "ext_sense.commands.bags",  # record, replay
    "ext_sense.commands.demo",  # demo (the main job)
    "ext_sense.commands.models",  # models create|list
    "ext_sense.commands.collect",  # collect TASK OUT
    "ext_sense.commands.plot",  # plot BAG|CAPTURE_FOLDER
    "ext_sense_drivers.cli",  # nuskin ..., biotac ...
    "ext_sense_sim.cli",  # sim list|run|serve
    "ext_sense_perception.cli",  # features, train, evaluate, report
)

NOT_STARTED = "[run] stopped before any node started"
"""What ``ext-sense run`` prints when Ctrl-C lands before it started a node."""


def build_parser() -> argparse.ArgumentParser:
    """The full argument parser with every package's subcommands."""
    import argparse
    import importlib

    parser = argparse.ArgumentParser(
        prog="ext-sense",
        description="Extended tactile perception: drivers, simulator, learning and the ROS 2 "
        "node graphs of ext_sense.",
    )
    subparsers = parser.add_subparsers(dest="command", metavar="COMMAND")
    subparsers.required = True
    for name in COMMAND_MODULES:
        try:
            module = importlib.import_module(name)
        except ModuleNotFoundError as err:
            if err.name is not None and name.startswith(err.name):
                continue  # that package is not installed on this machine
            raise
        module.register(subparsers)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Run ``ext-sense``; returns the process exit code.

    Ctrl-C ends a command with 130, except ``run``, whose normal end it is (0, one line), also
    before any node started. With ``argv`` ``None`` (the console script) a Ctrl-C ends the
    process itself (:func:`_end_interrupted`).
    """
    as_process = argv is None
    argv = list(sys.argv[1:] if argv is None else argv)
    try:
        if argv[:1] == ["run"]:
            hear_interrupts()
        return _dispatch(argv)
    except KeyboardInterrupt:
        if argv[:1] == ["run"]:
            print(NOT_STARTED, file=sys.stderr)
            code = 0
        else:
            print("ext-sense: interrupted", file=sys.stderr)
            code = 130
        if as_process:
            _end_interrupted(code)
        return code
    except BrokenPipeError:  # e.g. piped into `head`
        return 0


def hear_interrupts() -> None:
    """Let Ctrl-C stop ``run`` from here on, also when it was started with SIGINT ignored.

    A shell without job control starts background commands with SIGINT ignored; the runner's
    handlers take SIGINT anyway, so the command takes it from its first line on too.
    """
    import signal

    if signal.getsignal(signal.SIGINT) is signal.SIG_IGN:
        signal.signal(signal.SIGINT, signal.default_int_handler)


def _end_interrupted(code: int) -> NoReturn:
    """End this process with ``code`` now, after a caught Ctrl-C.

    A ``KeyboardInterrupt`` inside a builtin ``eval()`` (``collections.namedtuple`` while
    importing) sets a CPython flag no ``except`` clears, and CPython then kills the process
    with SIGINT at exit (issue #15, docs/runtime.md). Nothing is left to finalise here.
    """
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(code)


def _dispatch(argv: list[str]) -> int:
    parser = build_parser()
    # `name:=value` arguments may stand anywhere (argparse cannot say so): taken out here for
    # the subcommands that declare `accepts_assignments`
    assignments = [a for a in argv if ":=" in a and not a.startswith("-")]
    args = parser.parse_args([a for a in argv if a not in assignments])
    if assignments and not getattr(args, "accepts_assignments", False):
        parser.error(f"unrecognized arguments: {' '.join(assignments)}")
    args.assignments = assignments
    return int(args.func(args) or 0)


if __name__ == "__main__":
    sys.exit(main())
