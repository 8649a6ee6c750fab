"""``ext-sense collect``'s core (no ROS): prompts, answers, kept trials, ``collect.json``."""

from __future__ import annotations

import json
import math
import random
from collections import Counter
from collections.abc import Iterable, Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path

STATE_FILE = "collect.json"
TASKS = ("tap_localization", "handover_stability", "food_identification")
GRAPH_OF_TASK = {
    "tap_localization": "tap_localization",
    "handover_stability": "handover",
    "food_identification": "food_identification",
}
HANDOVER_CLASSES = ("stable", "unstable")
FOOD_CLASSES = ("empty", "water", "tofu", "banana", "watermelon", "apple", "green_pepper")
KEEP, REDO, DISCARD, QUIT = "keep", "redo", "discard", "quit"
COMMANDS = (KEEP, REDO, DISCARD, QUIT)
HANDOVER_END_STATES = ("RELEASED", "TIMED_OUT", "FAULT")
"""Handover decisions that end a grasp: the object was let go, the safety timeout, a fault."""


class CollectError(ValueError):
    """A bad answer, plan or state file (the message names what was expected)."""


def tap_sequence(n: int, low_m: float, high_m: float, seed: int) -> list[float]:
    """``n`` tap positions evenly over ``[low_m, high_m]``, rounded to 1 mm, shuffled.

    Shuffled so the operator's drift over a session does not line up with position.
    """
    if n < 1 or not 0.0 <= low_m < high_m:
        raise CollectError(
            f"The tap range must be 0 <= low < high with n >= 1. Got n={n}, "
            f"[{low_m}, {high_m}] instead."
        )
    step = (high_m - low_m) / max(n - 1, 1)
    positions = [round(low_m + k * step, 3) for k in range(n)]
    random.Random(seed).shuffle(positions)
    return positions


def class_sequence(classes: Sequence[str], n: int, seed: int) -> list[str]:
    """``n`` classes as balanced as ``n`` allows, shuffled (each class ``n // k`` or one more)."""
    if not classes or n < 1:
        raise CollectError(f"Need classes and n >= 1. Got {list(classes)}, n={n} instead.")
    seq = [classes[k % len(classes)] for k in range(n)]
    random.Random(seed).shuffle(seq)
    return seq


@dataclass
class Trial:
    """One kept trial: its label and the onsets its ground truth is stamped with.

    ``label`` is a class or a tap position in metres as text (``"0.125"``); ``onsets_ns`` has
    one host epoch stamp per window; ``truth`` is what mocap or the simulator said, or ``""``.
    """

    index: int
    label: str
    onsets_ns: list[int]
    truth: str = ""


@dataclass
class CollectState:
    """A session's progress, saved after every change; ``attempts``: trials played, kept or not."""

    task: str
    planned: list[str]
    trials: list[Trial] = field(default_factory=list)
    prompt_index: int = 0
    next_index: int = 0
    attempts: int = 0

    @property
    def done(self) -> bool:
        """Every planned trial is kept."""
        return len(self.trials) >= len(self.planned)

    def prompt(self) -> str:
        """The planned label of the next trial (wraps when trials were discarded)."""
        return self.planned[self.prompt_index % len(self.planned)]

    def keep(self, label: str, onsets_ns: Sequence[int], truth: str = "") -> Trial:
        """Keep a trial; the next prompt moves on."""
        trial = Trial(self.next_index, label, [int(t) for t in onsets_ns], truth)
        self.trials.append(trial)
        self.next_index += 1
        self.prompt_index += 1
        return trial

    def discard_last(self) -> Trial | None:
        """Drop the last kept trial (its prompt comes again); None when there is none."""
        if not self.trials:
            return None
        self.prompt_index = max(0, self.prompt_index - 1)
        return self.trials.pop()

    def counts(self) -> Counter[str]:
        """Kept trials per class (tap: per 5 cm bin)."""
        if self.task == "tap_localization":
            return Counter(f"{5 * math.floor(float(t.label) * 20)}cm" for t in self.trials)
        return Counter(t.label for t in self.trials)

    def progress(self, estimate: str = "") -> str:
        """The terminal's status line: trial n of N, counts per class, the live estimate."""
        counts = " ".join(f"{k}={v}" for k, v in sorted(self.counts().items(), key=_natural))
        line = f"[{len(self.trials)}/{len(self.planned)}] {counts}".rstrip()
        return f"{line} | estimate {estimate}" if estimate else line

    def save(self, directory: Path) -> Path:
        """Write ``collect.json`` in ``directory`` atomically."""
        path = directory / STATE_FILE
        tmp = path.with_suffix(".tmp")
        tmp.write_text(json.dumps(asdict(self), indent=1) + "\n")
        tmp.replace(path)
        return path

    @classmethod
    def load(cls, directory: Path) -> CollectState:
        """The state of an interrupted session (CollectError: none, or one that does not parse)."""
        path = directory / STATE_FILE
        try:
            raw = json.loads(path.read_text())
            raw["trials"] = [Trial(**t) for t in raw["trials"]]
            return cls(**raw)
        except (OSError, KeyError, TypeError, json.JSONDecodeError) as err:
            raise CollectError(f"Cannot resume from {str(path)!r}: {err}") from err


def parse_command(text: str) -> str:
    """An answer's command word (``k``/``keep``, ``r``/``redo``, ``d``/``discard``, ``q``)."""
    word = text.strip().lower()
    for cmd in COMMANDS:
        if word in (cmd, cmd[0]):
            return cmd
    return ""


def parse_class(text: str, classes: Sequence[str]) -> str:
    """A class answer: the name or its 1-based number in ``classes`` (CollectError: neither)."""
    word = text.strip().lower().replace(" ", "_")
    if word.isdigit() and 1 <= int(word) <= len(classes):
        return classes[int(word) - 1]
    for name in classes:
        if word == name or (len(word) >= 2 and name.startswith(word)):
            return name
    raise CollectError(
        f"The answer must be one of {list(classes)} or 1..{len(classes)}. Got "
        f"{text.strip()!r} instead."
    )


def read_answers(path: Path) -> list[str]:
    """Scripted answers: one per prompt, blank lines and ``#`` comments skipped."""
    lines = (ln.split("#", 1)[0].strip() for ln in path.read_text().splitlines())
    return [ln for ln in lines if ln]


class Answers:
    """Where answers come from: a script (``--answers``) or the terminal."""

    def __init__(self, scripted: Iterable[str] | None = None) -> None:
        self._script: list[str] | None = list(scripted) if scripted is not None else None
        self._next = 0

    def peek(self) -> str | None:
        """The next scripted answer without taking it; None from the terminal or past the end."""
        if self._script is None or self._next >= len(self._script):
            return None
        return self._script[self._next]

    def ask(self, prompt: str) -> str:
        """The next answer; a script that runs out answers ``quit`` (the session is resumable)."""
        if self._script is None:
            try:
                return input(prompt + " ")
            except EOFError:
                return QUIT
        answer = self.peek() or QUIT
        self._next += 1
        print(f"{prompt} {answer}", flush=True)
        return answer


def sim_schedule(task: str, answers: Sequence[str], classes: Sequence[str]) -> list[str]:
    """The simulator's ``labels`` for a scripted food session: each named food, in order."""
    if task != "food_identification":
        return []
    schedule: list[str] = []
    for text in answers:
        cmd = parse_command(text)
        if cmd == QUIT:
            break
        if not cmd:
            schedule.append(parse_class(text, classes))
    return schedule


def grasp_class(answer: str | None, classes: Sequence[str]) -> str:
    """The class a grasp must be played as for the pending ``answer``; ``""``: the scene's draw."""
    if answer is None or parse_command(answer):
        return ""
    try:
        return parse_class(answer, classes)
    except CollectError:
        return ""


def parse_decision(text: str) -> tuple[int, str]:
    """``(stamp_ns, state)`` of a decision published ``[stamp] STATE: ...`` (else CollectError)."""
    try:
        stamp, rest = text.split("] ", 1)
        return int(stamp.lstrip("[")), rest.split(":", 1)[0]
    except ValueError as err:
        raise CollectError(f"A decision must read '[stamp_ns] STATE: ...'. Got {text!r}.") from err


def grasp_end(offer_ns: int, decisions: Sequence[tuple[int, str]]) -> int | None:
    """When the grasp offered at ``offer_ns`` ended (:data:`HANDOVER_END_STATES`); None: not yet."""
    ends = [t for t, state in decisions if t >= offer_ns and state in HANDOVER_END_STATES]
    return min(ends, default=None)


def grasp_windows(offer_ns: int, end_ns: int, onsets: Iterable[int]) -> list[int]:
    """The window onsets of the grasp from its offer to its end, in order, each once."""
    return sorted({t for t in onsets if offer_ns <= t <= end_ns})


def window_note(model_end_ns: int, probe_end_ns: int) -> str:
    """Why a food probe can have no live estimate (the model's window outlasts it), or ``""``."""
    if model_end_ns <= probe_end_ns:
        return ""
    return (
        f"the model's window ends {model_end_ns / 1e9:.1f} s after the motion start, the probe "
        f"{probe_end_ns / 1e9:.1f} s: no estimate, or one from a truncated window"
    )


def match_truth(onset_ns: int, truths: Sequence[tuple[int, str]], tolerance_ns: int) -> str:
    """The independent truth stamped nearest ``onset_ns``; ``""`` when none within tolerance."""
    best = min(truths, key=lambda t: abs(t[0] - onset_ns), default=None)
    if best is None or abs(best[0] - onset_ns) > tolerance_ns:
        return ""
    return best[1]


def _natural(item: tuple[str, int]) -> tuple[int, str]:
    """Sort ``5cm`` before ``25cm``: numbers by value, names by name."""
    digits = "".join(c for c in item[0] if c.isdigit())
    return (int(digits) if digits else -1, item[0])
