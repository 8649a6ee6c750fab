"""Bags from a simulator ``dataset.npz`` (format in docs/conventions.md), for replay and tests.

Trials are laid on one timeline, ``trial_period_ns`` apart from ``t0_ns``; each trial's
ground truth is stamped at its onset (food: motion start). NUSkin events become
``TaxelEventBatch`` messages of ``batch_ns`` each; BioTac PAC becomes ``BioTacFrame`` messages
of 22 samples (slow channels repeated per frame at their 100 Hz sample).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ext_sense_bags.errors import BagError
from ext_sense_bags.messages import biotac_frame, ground_truth, taxel_event_batch
from ext_sense_bags.writer import BagWriter, Storage

EVENTS = "/extsense/nuskin/events"
FRAMES = "/extsense/biotac/frames"
TRUTH = "/extsense/ground_truth"
PAC_PER_FRAME = 22
PAC_PERIOD_NS = 454_545
SLOW_PERIOD_NS = 10_000_000


def dataset_to_bag(
    dataset: str | Path,
    out: str | Path,
    *,
    t0_ns: int = 1_700_000_000_000_000_000,
    trial_period_ns: int = 1_000_000_000,
    batch_ns: int = 1_000_000,
    trials: int | None = None,
    storage: Storage | str = Storage.MCAP,
) -> int:
    """Write a bag holding a dataset's sensor stream and ground truth.

    Args:
        dataset: The simulator's ``dataset.npz``.
        out: Directory of the new bag.
        t0_ns: Host time of trial 0's origin, ns.
        trial_period_ns: Time between trial origins, ns (longer than a trial).
        batch_ns: NUSkin batch length, ns.
        trials: Only the first ``trials`` trials (all when None).
        storage: :class:`~ext_sense_bags.writer.Storage` or ``"mcap"``/``"sqlite3"``.

    Returns:
        Messages written.

    Raises:
        BagError: The dataset misses a field or holds an unknown sensor.
    """
    try:
        with np.load(dataset) as npz:
            d = {k: npz[k] for k in npz.files}
    except (OSError, ValueError) as err:
        raise BagError(f"Cannot read dataset {dataset}: {err}") from err
    for key in ("task", "sensor", "y", "onset_ns"):
        if key not in d:
            raise BagError(f"Dataset {dataset} has no field {key!r}.")
    task, sensor = str(d["task"]), str(d["sensor"])
    n = len(d["y"]) if trials is None else min(trials, len(d["y"]))
    regression = str(d.get("label_kind", "")) == "regression"
    rod = d.get("rod_length_m", np.full(len(d["y"]), np.nan))
    written = 0
    with BagWriter(out, storage) as bag:
        bag.set_custom_data("task", task)
        bag.set_custom_data("sensor", sensor)
        for i in range(n):
            origin = t0_ns + i * trial_period_ns
            onset = origin + int(d["onset_ns"][i])
            label = d["y"][i]
            msg = ground_truth(
                onset,
                task,
                i,
                tap_position_m=float(label) if regression else float("nan"),
                rod_length_m=float(rod[i]),
                class_label="" if regression else str(label),
            )
            # written first: a trial's truth precedes its data, as the live simulator sends it
            bag.write(TRUTH, origin, msg)
            written += 1
            if sensor == "nuskin":
                written += _write_events(bag, d, i, origin, batch_ns)
            elif sensor == "biotac":
                written += _write_frames(bag, d, i, origin)
            else:
                raise BagError(f"Dataset {dataset}: unknown sensor {sensor!r}.")
    return written


def _write_events(bag: BagWriter, d: dict, i: int, origin: int, batch_ns: int) -> int:
    sel = d["ev_trial"] == i
    t = d["ev_t_ns"][sel].astype(np.int64)
    order = np.argsort(t, kind="stable")
    t = t[order]
    taxel, pol, val = (d[k][sel][order] for k in ("ev_taxel", "ev_polarity", "ev_value"))
    end = int(d.get("trial_ns", t[-1] + 1 if len(t) else batch_ns))
    edges = np.searchsorted(t, np.arange(0, end + batch_ns, batch_ns))
    count = 0
    for k in range(len(edges) - 1):
        lo, hi = edges[k], edges[k + 1]
        stamp = origin + k * batch_ns
        msg = taxel_event_batch(
            stamp, taxel[lo:hi], pol[lo:hi], val[lo:hi], t[lo:hi] - k * batch_ns
        )
        bag.write(EVENTS, stamp + batch_ns, msg)
        count += 1
    return count


def _write_frames(bag: BagWriter, d: dict, i: int, origin: int) -> int:
    pac = d["pac"][i]  # (n_sensors, n_samples)
    t0 = origin + int(d.get("pac_t0_ns", np.zeros(len(d["y"]), np.int64))[i])
    n_frames = pac.shape[1] // PAC_PER_FRAME
    slow = {k: d[k][i] for k in ("pdc", "tac", "tdc", "electrodes") if k in d}
    count = 0
    for f in range(n_frames):
        stamp = t0 + f * PAC_PER_FRAME * PAC_PERIOD_NS
        j = min(f * PAC_PER_FRAME * PAC_PERIOD_NS // SLOW_PERIOD_NS, pac.shape[1])
        for s in range(pac.shape[0]):
            chunk = pac[s, f * PAC_PER_FRAME : (f + 1) * PAC_PER_FRAME]

            def slow_value(key: str, s: int = s, j: int = j) -> object:
                arr = slow.get(key)
                if arr is None:
                    return 0 if key != "electrodes" else np.zeros(19)
                return arr[s, min(j, arr.shape[1] - 1)]

            msg = biotac_frame(
                stamp,
                chunk,
                slow_value("electrodes"),
                int(slow_value("pdc")),
                int(slow_value("tac")),
                int(slow_value("tdc")),
                sensor_id=s,
                sequence=f,
                frame_id=f"biotac_{s}",
            )
            bag.write(FRAMES, stamp + PAC_PER_FRAME * PAC_PERIOD_NS, msg)
            count += 1
    return count
