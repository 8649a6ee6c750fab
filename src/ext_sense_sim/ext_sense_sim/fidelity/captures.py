"""Real captures and simulated trials, both at the host's 10 ms time resolution.

The lab's host wrote each event's time with two decimals, so a simulated trial is reduced to the
same: its event times shifted by a random phase within one bin and floored to 10 ms bins. A
simulated tap is first read the way the rod demo's host read its receiver (:func:`read_times`).
"""

from __future__ import annotations

import dataclasses
import datetime as dt
import re
from collections.abc import Sequence
from pathlib import Path
from typing import NamedTuple

import numpy as np
import numpy.typing as npt

from ext_sense_perception.data.importers import food_poking_trials, read_paper_tact
from ext_sense_perception.errors import PerceptionError
from ext_sense_perception.profiles import CAPTURE_LEAD_NS
from ext_sense_runtime.enums import Sensor, Task
from ext_sense_runtime.stamps import MS
from ext_sense_sim.dataset import DatasetCollector
from ext_sense_sim.engine import Simulator
from ext_sense_sim.fidelity.errors import FidelityError
from ext_sense_sim.scene import Scene

BIN_NS = 10 * MS
TRANSFER_WORDS = 510
"""Words in one full USB transfer from the rod demo's receiver: in the real tap windows 11.7 %
of the 10 ms bins of 24 March hold exactly 510 events, 24.1 % of 25 March's exactly 496 (a
2 KB transfer of a high- and of a full-speed adapter); no other count is a tenth as common."""
LATENCY_NS = 16 * MS
"""The USB serial adapter's latency timer (the FTDI default): a transfer that has not filled
within it goes to the host short. It sets the real rate spectrum's 24-48 Hz power."""
TAP_FILES = "temp_signal*.tact"
"""The lab's real-time rod demo wrote one capture per tap under this name."""
FOOD_FILES = "*_zero_*.tact"


class Capture(NamedTuple):
    """One real capture or simulated trial, event times as 10 ms bins from its first (0).

    ``mark_bin`` is a known instant's bin (a simulated tap's onset, a food trial's motion
    start; -1: unknown); ``label`` the food class (``""`` for taps).
    """

    name: str
    label: str
    bins: npt.NDArray[np.int64]
    taxel: npt.NDArray[np.uint16]
    polarity: npt.NDArray[np.int8]
    value: npt.NDArray[np.uint16]
    span_bins: int
    mark_bin: int

    @property
    def size(self) -> int:
        """Number of events."""
        return int(self.bins.shape[0])


class Session(NamedTuple):
    """The captures of one real session (or of one simulated run)."""

    name: str
    path: str
    captures: list[Capture]


def to_bins(t_ns: npt.NDArray[np.int64], origin_ns: int) -> npt.NDArray[np.int64]:
    """Host-stamped times (multiples of 10 ms as written) to bins from ``origin_ns``."""
    return np.round((np.asarray(t_ns, np.int64) - origin_ns) / BIN_NS).astype(np.int64)


def rod_cm(scene: Scene) -> int:
    """The scene's rod length in whole centimetres (:class:`FidelityError` if no rod)."""
    if scene.geometry.kind != "rod":
        raise FidelityError(
            f"Scene '{scene.name}' holds a {scene.geometry.kind}, not a rod: real rod-tap "
            "captures cannot be matched with it."
        )
    return round(scene.geometry.length_m * 100)


def tap_folder(path: str | Path, rod: int) -> tuple[str, Path]:
    """The session name and folder of ``rod`` cm captures of a day's or a ``rodNN/`` folder."""
    path = Path(path)
    if not path.is_dir():
        raise FidelityError(f"The --real folder {str(path)!r} does not exist.")
    if any(path.glob(TAP_FILES)):
        match = re.fullmatch(r"rod(\d+)", path.name)
        if match and int(match.group(1)) != rod:
            raise FidelityError(
                f"The --real folder {str(path)!r} holds captures of the {match.group(1)} cm "
                f"rod; the scene's rod is {rod} cm."
            )
        return path.resolve().parent.name, path
    sub = path / f"rod{rod}"
    if not any(sub.glob(TAP_FILES)):
        raise FidelityError(
            f"The --real folder {str(path)!r} holds no rod-tap captures ({TAP_FILES}), "
            f"neither itself nor in rod{rod}/ (the scene's rod is {rod} cm)."
        )
    return path.resolve().name, sub


def _capture_number(path: Path) -> tuple[int, str]:
    digits = re.sub(r"\D", "", path.stem)
    return (int(digits) if digits else -1, path.name)


def read_tap_session(path: str | Path, rod: int) -> Session:
    """Every rod-tap capture of one ``--real`` folder for the ``rod`` cm rod, by file number."""
    name, folder = tap_folder(path, rod)
    captures = []
    for tact in sorted(folder.glob(TAP_FILES), key=_capture_number):
        try:
            ev = read_paper_tact(tact, markers=False)
        except PerceptionError as err:
            raise FidelityError(str(err)) from err
        origin = int(ev.t_ns[0]) if ev.size else 0
        bins = to_bins(ev.t_ns, origin)
        span = int(bins[-1]) + 1 if ev.size else 0
        captures.append(Capture(tact.stem, "", bins, ev.taxel, ev.polarity, ev.value, span, -1))
    return Session(name, str(folder), captures)


def read_food_session(path: str | Path) -> Session:
    """Every food-poking trial (the ``empty`` one included) of one ``--real`` folder.

    The session is named by its folder, plus the day of its first capture when the name holds
    no date. The motion start comes from each trial's arm bag when every trial has one, else
    from the capture's start plus ``CAPTURE_LEAD_NS`` (the lab's own alignment).
    """
    path = Path(path)
    if not path.is_dir():
        raise FidelityError(f"The --real folder {str(path)!r} does not exist.")
    tacts = [p for p in path.glob(FOOD_FILES) if not p.name.endswith("_raw.tact")]
    if not tacts:
        raise FidelityError(
            f"The --real folder {str(path)!r} holds no food-poking captures ({FOOD_FILES})."
        )
    arm = all(p.with_suffix(".bag").is_file() for p in tacts)
    try:
        recs, _ = food_poking_trials(path, include_empty=True, arm_motion=arm)
    except PerceptionError as err:
        raise FidelityError(str(err)) from err
    captures = []
    for rec in recs:
        ev, origin = rec.events, rec.capture_start_ns
        start = rec.motion.start_ns if rec.motion is not None else origin + CAPTURE_LEAD_NS
        bins = to_bins(ev.t_ns, origin)
        span = int(bins[-1]) + 1 if ev.size else 0
        mark = (start - origin) // BIN_NS
        captures.append(
            Capture(rec.name, rec.label, bins, ev.taxel, ev.polarity, ev.value, span, mark)
        )
    name = path.resolve().name
    if recs and not re.search(r"\d{4}-\d{2}-\d{2}", name):
        day = dt.datetime.fromtimestamp(recs[0].capture_start_ns / 1e9, tz=dt.timezone.utc)
        name = f"{name}_{day.date().isoformat()}"
    return Session(name, str(path), captures)


def check_kind(scene: Scene) -> Task:
    """The scene's task, if real captures of it exist (NUSkin taps or food), else an error."""
    if scene.sensor is not Sensor.NUSKIN:
        raise FidelityError(
            f"Scene '{scene.name}' simulates the {scene.sensor.label}; the real captures are "
            "NUSkin's: give a NUSkin scene (e.g. tap_rod30_nuskin, food_fork_nuskin)."
        )
    if scene.task not in (Task.TAP_LOCALIZATION, Task.FOOD_IDENTIFICATION):
        raise FidelityError(
            f"Scene '{scene.name}' simulates {scene.task.label}, which has no real captures; "
            "fidelity compares NUSkin tap and food scenes."
        )
    return scene.task


def read_sessions(scene: Scene, paths: Sequence[str | Path]) -> list[Session]:
    """The real sessions of ``--real`` folders, read for the scene's task (taps: its rod)."""
    if check_kind(scene) is Task.FOOD_IDENTIFICATION:
        return [read_food_session(path) for path in paths]
    return [read_tap_session(path, rod_cm(scene)) for path in paths]


def read_times(
    t_ns: npt.NDArray[np.int64], words: int = TRANSFER_WORDS, latency_ns: int = LATENCY_NS
) -> npt.NDArray[np.int64]:
    """When a host reading a USB serial adapter gets each word of one trial (sorted times).

    A transfer opens with the first word after the previous one closed and closes when it holds
    ``words`` words or ``latency_ns`` after it opened; the host stamps all its words then. So
    a burst arrives in full transfers (the real captures' bins of exactly 510 or 496 events)
    and a slower stream every latency period (their empty bins between busy ones).
    """
    t_ns = np.asarray(t_ns, np.int64)
    out = np.empty_like(t_ns)
    i = 0
    while i < t_ns.size:
        close = int(t_ns[i]) + latency_ns
        full = i + words - 1
        if full < t_ns.size and t_ns[full] <= close:
            close, end = int(t_ns[full]), full + 1
        else:
            end = int(np.searchsorted(t_ns, close, side="right"))
        out[i:end] = close
        i = end
    return out


def simulate(scene: Scene, trials: int, seed: int, extra_s: float = 0.0) -> Session:
    """Simulate ``trials`` trials of a NUSkin scene and reduce them to 10 ms host bins.

    ``extra_s`` lengthens each trial (a tap's window may run past ``trial_s``); the host-clock
    phases come from a generator of their own. Taps are read through :func:`read_times`; food
    trials are not (their few hundred events a second show no transfers to fit it to).
    """
    longer = dataclasses.replace(scene, trial_s=scene.trial_s + extra_s)
    sim = Simulator(longer)
    collector = DatasetCollector(longer, seed)
    for tb, signals in sim.batches(trials, seed):
        collector.add(tb, signals)
    arrays = collector.arrays()
    n = int(arrays["trial"].size)
    phase = np.random.default_rng([int(seed), 10]).integers(0, BIN_NS, n)
    bounds = np.searchsorted(arrays["ev_trial"], np.arange(n + 1))
    trial_ns = int(arrays["trial_ns"])
    food = scene.task is Task.FOOD_IDENTIFICATION
    captures = []
    for i in range(n):
        sl = slice(bounds[i], bounds[i + 1])
        t_ns = arrays["ev_t_ns"][sl] if food else read_times(arrays["ev_t_ns"][sl])
        end_ns = max(trial_ns, int(t_ns[-1]) if t_ns.size else 0)  # the last read may be later
        captures.append(
            Capture(
                name=f"trial_{i:04d}",
                label=str(arrays["y"][i]) if food else "",
                bins=(t_ns + phase[i]) // BIN_NS,
                taxel=arrays["ev_taxel"][sl],
                polarity=arrays["ev_polarity"][sl],
                value=arrays["ev_value"][sl],
                span_bins=int(-(-(end_ns + phase[i]) // BIN_NS)),
                mark_bin=int((arrays["onset_ns"][i] + phase[i]) // BIN_NS),
            )
        )
    return Session(f"simulated {scene.name}", str(scene.path or scene.name), captures)
