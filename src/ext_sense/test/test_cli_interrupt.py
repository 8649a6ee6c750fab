"""A Ctrl-C that ``ext-sense`` catches ends its process with the exit code it chose (issue #15).

Started with ``python -m``, CPython kills its own process with SIGINT at exit when a
``KeyboardInterrupt`` left a builtin ``eval()`` of a string, even one caught later
(docs/runtime.md "Stopping a graph"); the runner met it while still importing
(``collections.namedtuple`` evals), exiting -2 instead of 0. Started as a script (the
``ext-sense`` console script) it exited with its code; both are checked.
"""

from __future__ import annotations

import subprocess
import sys

import pytest

from ext_sense.cli import NOT_STARTED

INTERRUPTED_IN_EVAL = """
import sys
import ext_sense.cli as cli

def interrupted_in_eval(argv):
    def stop():
        raise KeyboardInterrupt
    eval("stop()", {"stop": stop})  # as a Ctrl-C inside namedtuple's eval

cli._dispatch = interrupted_in_eval
sys.exit(cli.main())
"""


@pytest.mark.parametrize("started_as", ["script", "module"])
@pytest.mark.parametrize(
    ("args", "code", "line"),
    [
        (["run", "tap_localization"], 0, NOT_STARTED),
        (["train", "--help"], 130, "ext-sense: interrupted"),
    ],
)
def test_a_ctrl_c_caught_during_start_up_ends_the_process_with_its_exit_code(
    tmp_path, started_as, args, code, line
):
    (tmp_path / "interrupted_cli.py").write_text(INTERRUPTED_IN_EVAL)
    how = ["interrupted_cli.py"] if started_as == "script" else ["-m", "interrupted_cli"]
    done = subprocess.run(
        [sys.executable, *how, *args],
        capture_output=True,
        text=True,
        timeout=60,
        cwd=tmp_path,
    )
    assert (done.returncode, done.stderr.strip()) == (code, line)


HANDLER_AFTER_MAIN = """
import signal
import sys
import ext_sense.cli as cli

cli._dispatch = lambda argv: 0  # nothing to run: only main's own set-up
before = signal.getsignal(signal.SIGINT)
cli.main(sys.argv[1:])
after = signal.getsignal(signal.SIGINT)
print(before is signal.SIG_IGN, after is signal.default_int_handler)
"""


@pytest.mark.parametrize(("command", "heard"), [("run", "True"), ("train", "False")])
def test_run_hears_ctrl_c_when_started_with_sigint_ignored(command, heard):
    """A shell without job control starts background commands with SIGINT ignored; ``run``
    installs Python's ``KeyboardInterrupt`` handler anyway (its graph stops on SIGINT), the
    other commands keep what they were given."""
    ignoring = ["sh", "-c", 'trap "" INT; exec "$@"', "sh"]
    out = subprocess.run(
        [*ignoring, sys.executable, "-c", HANDLER_AFTER_MAIN, command],
        capture_output=True,
        text=True,
        timeout=60,
        check=True,
    ).stdout.split()
    assert out == ["True", heard]
