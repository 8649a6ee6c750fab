"""Trials simulated ahead in a child process at low priority: the emulated world off the hot path.

A real sensor costs the robot's computer nothing; simulated in the device's own process, each
trial's burst of CPU fell on the nodes it feeds. :class:`TrialsAhead` runs ``plan_trials`` in a
child process at ``nice`` +10 and hands the same trials over a pipe, up to :data:`AHEAD_TRIALS`
ahead, as one trigger of a class can skip many trials of the others (docs/benchmarks.md, "The
emulator's look-ahead"). The child runs in a session of its own, so the graph's Ctrl-C reaches
only the device, which ends it; it also ends when the pipe closes, so it is never orphaned.
"""

from __future__ import annotations

import contextlib
import os
import pickle
import queue
import select
import subprocess
import sys
import threading
from collections.abc import Iterator
from typing import BinaryIO

from ext_sense_sim.errors import SceneError
from ext_sense_sim.scene import Scene
from ext_sense_sim.trial_plan import PlannedTrial, plan_trials

AHEAD_TRIALS = 64
"""Trials the child keeps simulated ahead of the device (pickled, waiting for the pipe)."""
WORLD_NICE = 10
"""How much lower than the device's the child's priority is (``nice`` increment)."""
POLL_S = 0.1
"""How often a wait for the next trial looks at ``stop`` and at the child."""


class _Failed:
    """The child's error, sent in place of a trial (as text: it must unpickle anywhere)."""

    def __init__(self, error: str) -> None:
        self.error = error


def simulate(scene: Scene, seed: int, out: BinaryIO, ahead: int = AHEAD_TRIALS) -> None:
    """The child's work: simulate trial after trial, keeping up to ``ahead`` ready for ``out``.

    A writer thread pickles them to ``out`` in order; simulation pauses while ``ahead`` wait
    and ends once the device's end of the pipe closed. An error is sent in place of a trial.
    """
    ready: queue.Queue[bytes | None] = queue.Queue(maxsize=max(1, int(ahead)))
    writer = threading.Thread(target=_write_all, args=(ready, out), daemon=True)
    writer.start()

    def put(item: bytes | None) -> bool:
        while writer.is_alive():
            try:
                ready.put(item, timeout=POLL_S)
                return True
            except queue.Full:
                continue
        return False

    try:
        for plan in plan_trials(scene, seed):
            if not put(pickle.dumps(plan, protocol=pickle.HIGHEST_PROTOCOL)):
                return
    except Exception as err:
        put(pickle.dumps(_Failed(f"{type(err).__name__}: {err}")))
    put(None)
    writer.join()


def _write_all(ready: queue.Queue[bytes | None], out: BinaryIO) -> None:
    """Write the pickled trials to ``out`` until ``None`` or a closed pipe."""
    while (item := ready.get()) is not None:
        try:
            out.write(item)
            out.flush()
        except OSError:  # BrokenPipeError included: the device's end closed
            return


class TrialsAhead(Iterator[PlannedTrial]):
    """``plan_trials(scene, seed)`` computed in a low-priority child process.

    Setting ``stop`` ends a wait for the next trial; ``next`` raises :class:`SceneError` when the
    scene cannot be streamed or the child ended.
    """

    def __init__(
        self, scene: Scene, seed: int, stop: threading.Event | None = None, nice: int = WORLD_NICE
    ) -> None:
        self.stop = stop or threading.Event()
        self._proc = subprocess.Popen(
            [sys.executable, "-m", __name__, str(int(seed)), str(int(nice))],
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            start_new_session=True,  # out of the graph's process group: its Ctrl-C is not ours
        )
        try:
            self._proc.stdin.write(pickle.dumps(scene, protocol=pickle.HIGHEST_PROTOCOL))
            self._proc.stdin.close()
        except OSError as err:
            self.close()
            raise SceneError(f"The trial simulator did not start: {err}") from err

    @property
    def pid(self) -> int:
        """The child's process id."""
        return self._proc.pid

    def __next__(self) -> PlannedTrial:
        out = self._proc.stdout
        while not self.stop.is_set():
            ready, _, _ = select.select([out], [], [], POLL_S)
            if not ready:
                continue
            try:
                item = pickle.load(out)
            except (EOFError, pickle.UnpicklingError):
                break
            if isinstance(item, _Failed):
                raise SceneError(f"The trial simulator failed: {item.error}")
            return item
        if self.stop.is_set():
            raise StopIteration
        code = self._proc.wait(timeout=5.0)
        raise SceneError(f"The trial simulator process ended (exit code {code}).")

    def alive(self) -> bool:
        """Whether the child still runs."""
        return self._proc.poll() is None

    def close(self) -> None:
        """End the child and wait for it."""
        if self._proc.poll() is None:
            self._proc.kill()
        self._proc.wait(timeout=5.0)
        self._proc.stdout.close()

    def __enter__(self) -> TrialsAhead:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def main(argv: list[str] | None = None) -> int:
    """The child (``python -m ext_sense_sim.trials_ahead SEED NICE``): the scene on stdin."""
    seed, nice = (int(a) for a in (argv if argv is not None else sys.argv[1:]))
    with contextlib.suppress(OSError):
        os.nice(nice)
    scene = pickle.load(sys.stdin.buffer)
    simulate(scene, seed, sys.stdout.buffer)
    return 0


if __name__ == "__main__":
    # run from the module imported by its name: what it pickles (``_Failed``) must unpickle in
    # the device, where ``__main__`` is another program
    from ext_sense_sim.trials_ahead import main as _main

    sys.exit(_main())
