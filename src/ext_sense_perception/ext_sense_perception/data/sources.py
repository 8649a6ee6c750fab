"""Window sets from every training source, cut by the online windowers' own cut (no ROS).

:func:`load_window_set` picks the reader by what the path is.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ext_sense_perception.data.bags import is_bag, window_set_from_bag
from ext_sense_perception.data.importers import (
    food_poking_trials,
    load_preprocessed_npz,
    load_sim_dataset,
)
from ext_sense_perception.data.refractory import refractory_mask
from ext_sense_perception.data.validation import RULE_LABEL, RULE_TAXEL, RULE_WINDOW, InputPolicy
from ext_sense_perception.data.window_set import WindowSet, file_hash, labels_of, window_set_of
from ext_sense_perception.errors import PerceptionError
from ext_sense_perception.online.model_card import HeldObject
from ext_sense_perception.online.model_input import Geometry
from ext_sense_perception.online.window import ContactWindow, WindowConfig, window_from_recording
from ext_sense_perception.online.windowers import EventWindower
from ext_sense_perception.profiles import CAPTURE_LEAD_NS, PAC_PERIOD_NS, Anchor, capture_profile
from ext_sense_runtime.enums import Sensor, Task
from ext_sense_runtime.records import EventBlock
from ext_sense_runtime.stamps import MS


def thinned(events: EventBlock, rate_hz: float | None) -> EventBlock:
    """The events after the per-taxel refractory drop to ``rate_hz`` (None: unchanged)."""
    if rate_hz is None:
        return events
    return events.select(refractory_mask(events.t_ns, events.taxel, rate_hz))


def from_sim_dataset(
    path: str | Path,
    config: WindowConfig | None = None,
    rate_hz: float | None = None,
    policy: InputPolicy | None = None,
) -> WindowSet:
    """Windows of the simulator's ``dataset.npz`` at each trial's onset (PerceptionError: bad file).

    ``config`` defaults to the task profile's; ``rate_hz`` thins NUSkin events before binning; a
    lenient ``policy`` drops and counts bad events and trials.
    """
    d = load_sim_dataset(path)
    task, sensor = (
        Task.parse(d["task"], PerceptionError),
        Sensor.parse(d["sensor"], PerceptionError),
    )
    config = config or WindowConfig.for_task(task, sensor)
    policy = policy or InputPolicy()
    onsets = np.asarray(d["onset_ns"], dtype=np.int64)
    n = len(onsets)
    labels = np.asarray(d["y"])
    keep_trial = np.ones(n, dtype=bool)
    trials = np.asarray(d.get("trial", np.arange(n)))
    if task.is_regression:
        y = labels.astype(np.float64)
        keep_trial = np.isfinite(y)
        policy.keep(~keep_trial, RULE_LABEL, f"dataset {str(path)!r} 'y' (trials)", y)
    windows = []
    if sensor is Sensor.NUSKIN:
        for key in ("ev_trial", "ev_t_ns", "ev_taxel"):
            if key not in d:
                raise PerceptionError(f"NUSkin dataset {str(path)!r} must hold {key!r}.")
        ev_trial = np.asarray(d["ev_trial"])
        order = np.argsort(ev_trial, kind="stable")
        ev_trial = ev_trial[order]
        taxel = np.asarray(d["ev_taxel"]).astype(np.float64)[order]
        ok = (taxel >= 1) & (taxel <= 80)
        policy.keep(~ok, RULE_TAXEL, f"dataset {str(path)!r} 'ev_taxel' (sorted by trial)", taxel)
        everything = EventBlock.of(
            np.asarray(d["ev_t_ns"], dtype=np.int64)[order],
            taxel.astype(np.uint16),
            np.asarray(d.get("ev_polarity", np.ones(len(order), np.int8)))[order],
        ).select(ok)
        ev_trial = ev_trial[ok]
        starts = np.searchsorted(ev_trial, trials, side="left")
        ends = np.searchsorted(ev_trial, trials, side="right")
        for i in range(n):
            events = everything.select(slice(starts[i], ends[i])).sorted_by_time()
            windows.append(
                window_from_recording(config, int(onsets[i]), events=thinned(events, rate_hz))
            )
    else:
        if "pac" not in d:
            raise PerceptionError(f"BioTac dataset {str(path)!r} must hold 'pac'.")
        pac = np.asarray(d["pac"])
        t0 = np.asarray(d.get("pac_t0_ns", np.zeros(n, np.int64)), dtype=np.int64)
        for i in range(n):
            windows.append(
                window_from_recording(config, int(onsets[i]), pac=pac[i], pac_t0_ns=int(t0[i]))
            )
    kind = str(d.get("label_kind", "regression" if task.is_regression else "classification"))
    if (kind == "regression") != task.is_regression:
        raise PerceptionError(
            f"Dataset {str(path)!r} has label_kind {kind!r}, which task {task.label!r} does not "
            "have."
        )
    rods = np.asarray(d.get("rod_length_m", np.full(n, np.nan)), dtype=np.float64)
    held = None
    if "object_kind" in d:  # the scene's object (older datasets: told from rod_length_m)
        length = float(d.get("object_length_m", np.nan))
        held = HeldObject(str(d["object_kind"]), length if np.isfinite(length) else None)
    ws = window_set_of(
        config,
        [w for w, k in zip(windows, keep_trial, strict=True) if k],
        labels[keep_trial],
        str(path),
        file_hash(path),
        groups=trials[keep_trial],
        rod_length_m=rods[keep_trial],
        n_channels=int(pac.shape[1]) if sensor is Sensor.BIOTAC and n else None,
        excluded=tuple(f"trial {int(t)}" for t in trials[~keep_trial]),
    )
    return ws._replace(held_object=held)


def food_capture_config(anchor: Anchor | str = Anchor.ARM_MOTION) -> WindowConfig:
    """The real food captures' windows at ``anchor`` (see ``profiles.capture_profile``).

    The captures end about 3.1 s after the arm starts moving, too early for the paper's 2-8 s
    window.
    """
    return WindowConfig.for_profile(capture_profile(anchor), Sensor.NUSKIN)


def default_anchor(directory: str | Path) -> Anchor:
    """``arm_motion`` if every trial of a capture folder has an arm bag, else ``capture_start``."""
    tacts = [p for p in Path(directory).glob("*_zero_*.tact") if not p.name.endswith("_raw.tact")]
    has_bags = bool(tacts) and all(p.with_suffix(".bag").is_file() for p in tacts)
    return Anchor.ARM_MOTION if has_bags else Anchor.CAPTURE_START


def _contact_window(config: WindowConfig, events: EventBlock) -> ContactWindow | None:
    """The first final window the live windower cuts from a whole capture (None: no contact)."""
    windower = EventWindower(config)
    windows = windower.feed(events) + windower.flush()
    final = [w for w in windows if not w.provisional]
    return final[0] if final else None


def from_food_poking(
    directory: str | Path,
    include_empty: bool = False,
    rate_hz: float | None = None,
    policy: InputPolicy | None = None,
    anchor: Anchor | str | None = None,
) -> WindowSet:
    """Windows of one session of real NUSkin food-poking captures (:func:`food_capture_config`).

    ``anchor`` defaults to :func:`default_anchor`; ``rate_hz`` thins the events before binning.
    PerceptionError: no trials, a missing ``arm_motion`` bag, a bad row, or no contact found.
    """
    anchor = default_anchor(directory) if anchor is None else Anchor.parse(anchor)
    recs, excluded = food_poking_trials(
        directory, include_empty, policy, arm_motion=anchor is Anchor.ARM_MOTION
    )
    config = food_capture_config(anchor)
    windows, labels = [], []
    for rec in recs:
        events = thinned(rec.events, rate_hz)
        if anchor is Anchor.CONTACT:
            window = _contact_window(config, events)
            if window is None:
                excluded.append(f"{rec.name} (no contact detected)")
                continue
        else:
            onset = (
                rec.motion.start_ns
                if rec.motion is not None
                else rec.capture_start_ns + CAPTURE_LEAD_NS
            )
            window = window_from_recording(config, onset, events=events)
        windows.append(window)
        labels.append(rec.label)
    if not windows:
        raise PerceptionError(
            f"No trial of {str(directory)!r} has a window at anchor {anchor.value!r}."
        )
    files = [
        p
        for p in sorted(Path(directory).glob("*_zero_*"))
        if p.suffix in (".tact", ".bag") and "_raw" not in p.name
    ]
    files = [p for p in files if p.stem.split("_zero_")[0] != "empty" or include_empty]
    ws = window_set_of(
        config, windows, labels, str(directory), file_hash(*files), excluded=tuple(excluded)
    )
    return ws._replace(anchor=anchor.value)


def from_preprocessed_npz(
    path: str | Path,
    task: str,
    sensor: str,
    frequency_hz: float | None = None,
    rate_hz: float | None = None,
    policy: InputPolicy | None = None,
) -> WindowSet:
    """The paper's preprocessed ``.npz`` as a window set (handover: ``isPos`` as stable/unstable).

    NUSkin: 5 ms bins from 50 ms before contact (handover v2 and food: from 0). BioTac: 2200 Hz (or
    ``frequency_hz``) from 100 samples before contact. PerceptionError: a NUSkin ``rate_hz`` (the
    file holds bin counts, not events), a malformed file, or a window breaking a rule.
    """
    task_e, sensor_e = Task.parse(task, PerceptionError), Sensor.parse(sensor, PerceptionError)
    if rate_hz is not None and sensor_e is Sensor.NUSKIN:
        raise PerceptionError(
            f"The 'rate_hz' parameter ({rate_hz} Hz) needs NUSkin events, but {str(path)!r} is "
            "the paper's preprocessed file of 5 ms bin counts. Use the .tact recordings "
            "(ext-sense features --data FILE.tact) for the sampling-rate study."
        )
    signals, labels = load_preprocessed_npz(path)
    labels = np.asarray(labels)
    if labels.ndim == 2:
        labels = labels[:, 0]
    if task_e is Task.HANDOVER_STABILITY:
        labels = np.where(labels.astype(float) > 0.5, "stable", "unstable")
    if sensor_e is Sensor.NUSKIN:
        period = 5 * MS if task_e is not Task.FOOD_IDENTIFICATION else 50 * MS
        pre = 50 * MS if task_e is Task.TAP_LOCALIZATION else 0
    else:
        period = PAC_PERIOD_NS if frequency_hz is None else round(1e9 / frequency_hz)
        pre = 100 * period
    policy = policy or InputPolicy()
    where = f"preprocessed {str(path)!r} (windows)"
    keep = np.isfinite(signals).all(axis=(1, 2))
    policy.keep(~keep, RULE_WINDOW, where)
    y, names = labels_of(labels, regression=task_e.is_regression)
    if task_e.is_regression:
        finite = np.isfinite(y)
        policy.keep(keep & ~finite, RULE_LABEL, where, y)
        keep &= finite
    signals, y = signals[keep], y[keep]
    if task_e.is_regression and len(y):
        y = y / 100.0 if np.max(np.abs(y)) > 2.0 else y  # the paper's labels are in cm
    geometry = Geometry(signals.shape[1], signals.shape[2], period, pre, sensor_e.label)
    n = len(signals)
    return WindowSet(
        task_e.label,
        sensor_e.label,
        signals,
        y,
        geometry,
        names,
        np.arange(n),
        np.full(n, np.nan),
        str(path),
        file_hash(path),
    )


def names_own_kind(data: str | Path) -> bool:
    """Whether the data says its own task and sensor (capture folders and simulator datasets do)."""
    path = Path(data)
    if path.is_dir():
        return not is_bag(path)
    if path.suffix != ".npz" or not path.is_file():
        return False
    try:
        with np.load(path, allow_pickle=False) as z:
            return "signals" not in z.files
    except (OSError, ValueError):
        return False  # load_window_set names what is wrong with the file


def load_window_set(
    data: str | Path,
    task: str | None = None,
    sensor: str | None = None,
    rate_hz: float | None = None,
    policy: InputPolicy | None = None,
    anchor: Anchor | str | None = None,
) -> WindowSet:
    """Any supported source as a window set, chosen by what ``data`` is.

    A bag, a food-poking directory, a simulator ``dataset.npz`` or a preprocessed ``.npz`` (which
    needs ``task`` and ``sensor``). ``anchor`` applies to capture folders only. PerceptionError: an
    unrecognised source, or an anchor for a source with its own onsets.
    """
    path = Path(data)
    if anchor is not None and not (path.is_dir() and not is_bag(path)):
        raise PerceptionError(
            f"The 'anchor' parameter applies to capture folders; {str(path)!r} holds its own "
            f"onsets (bags: --onsets truth|detected). Got {Anchor.parse(anchor).value!r}."
        )
    if is_bag(path):
        return window_set_from_bag(path, task, sensor, rate_hz=rate_hz)[0]
    if path.is_dir():
        return from_food_poking(path, rate_hz=rate_hz, policy=policy, anchor=anchor)
    if path.suffix == ".npz":
        try:
            with np.load(path, allow_pickle=False) as z:
                files = set(z.files)
        except (OSError, ValueError) as err:
            raise PerceptionError(f"Cannot read {str(path)!r}: {err}") from err
        if "signals" in files:
            if task is None or sensor is None:
                raise PerceptionError(
                    "The 'task' and 'sensor' parameters are needed for a preprocessed npz. Got "
                    "None."
                )
            return from_preprocessed_npz(path, task, sensor, rate_hz=rate_hz, policy=policy)
        ws = from_sim_dataset(path, rate_hz=rate_hz, policy=policy)
        if task is not None and Task.parse(task, PerceptionError).label != ws.task:
            raise PerceptionError(
                f"The 'task' parameter must match the dataset's {ws.task!r}. Got {task!r} instead."
            )
        if sensor is not None and Sensor.parse(sensor, PerceptionError).label != ws.sensor:
            raise PerceptionError(
                f"The 'sensor' parameter must match the dataset's {ws.sensor!r}. Got {sensor!r} "
                "instead."
            )
        return ws
    raise PerceptionError(
        "The 'data' parameter must be a bag, a food-poking directory or an .npz dataset. Got "
        f"{str(path)!r} instead."
    )
