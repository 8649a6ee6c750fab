"""rosbag2 (mcap) bag of a run: typed sensor messages plus the ground truth.

NUSkin events in 1 ms batches (the drivers' default batching) or BioTac frames, and the ground
truth stamped at the true onset; trial ``i`` starts at epoch ``BASE_EPOCH_S + i * trial_s``, and
log times equal header stamps, so ``ros2 bag play`` paces the bag as it was simulated.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ext_sense_sim.output.paper import BASE_EPOCH_S

BATCH_NS = 1_000_000


def write_bag(arrays: dict[str, np.ndarray], folder: Path, trial_s: float) -> list[Path]:
    """Write the run's bag into ``folder`` (a new directory); returns the files written."""
    from ext_sense_bags import BagWriter, biotac_frame, ground_truth, taxel_event_batch

    base = int(BASE_EPOCH_S * 1e9)
    trial_ns = round(trial_s * 1e9)
    task = str(arrays["task"])
    nuskin = str(arrays["sensor"]) == "nuskin"
    with BagWriter(folder) as bag:
        if nuskin:
            t_abs = base + arrays["ev_trial"].astype(np.int64) * trial_ns + arrays["ev_t_ns"]
            bins = t_abs // BATCH_NS
            edges = np.flatnonzero(np.diff(bins)) + 1
            for lo, hi in zip(np.r_[0, edges], np.r_[edges, bins.size], strict=True):
                if hi <= lo:
                    continue
                stamp = int(bins[lo] * BATCH_NS)
                bag.write(
                    "/extsense/nuskin/events",
                    stamp,
                    taxel_event_batch(
                        stamp,
                        arrays["ev_taxel"][lo:hi],
                        arrays["ev_polarity"][lo:hi],
                        arrays["ev_value"][lo:hi],
                        t_abs[lo:hi] - stamp,
                    ),
                )
        else:
            pac = arrays["pac"]
            n_trials, n_sensors, n_pac = pac.shape
            for i in range(n_trials):
                for f in range(n_pac // 22):
                    stamp = base + i * trial_ns + int(arrays["pac_t0_ns"][i]) + f * 10_000_000
                    for s in range(n_sensors):
                        bag.write(
                            "/extsense/biotac/frames",
                            stamp,
                            biotac_frame(
                                stamp,
                                pac[i, s, f * 22 : (f + 1) * 22],
                                arrays["electrodes"][i, s, f],
                                int(arrays["pdc"][i, s, f]),
                                int(arrays["tac"][i, s, f]),
                                int(arrays["tdc"][i, s, f]),
                                sensor_id=s,
                                sequence=(i * (n_pac // 22) + f),
                                frame_id=("biotac_left", "biotac_right")[s],
                            ),
                        )
        regression = str(arrays["label_kind"]) == "regression"
        for i in range(arrays["trial"].size):
            stamp = base + i * trial_ns + int(arrays["onset_ns"][i])
            bag.write(
                "/extsense/ground_truth",
                stamp,
                ground_truth(
                    stamp,
                    task,
                    i,
                    tap_position_m=float(arrays["y"][i]) if regression else float("nan"),
                    rod_length_m=float(arrays["rod_length_m"][i]),
                    class_label="" if regression else str(arrays["y"][i]),
                ),
            )
    return sorted(p for p in Path(folder).rglob("*") if p.is_file())
