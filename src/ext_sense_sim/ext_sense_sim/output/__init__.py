"""Writers of a run's outputs (dataset, the paper's formats, raw streams, bags)."""

from __future__ import annotations

from pathlib import Path

from ext_sense_runtime.enums import Sensor
from ext_sense_sim.dataset import DatasetCollector
from ext_sense_sim.scene import Scene


def write_outputs(
    scene: Scene, out: Path, collector: DatasetCollector, batches: list, formats: tuple[str, ...]
) -> list[Path]:
    """Write the requested outputs of one run into ``out``; returns the files written.

    ``raw`` needs a wire effect in the scene, ``bag`` the ``ext_sense_bags`` package.
    """
    from ext_sense_sim.output.paper import write_biotac_csv, write_tact
    from ext_sense_sim.output.raw import write_raw

    written: list[Path] = []
    arrays = collector.arrays()
    if "npz" in formats:
        written.append(collector.write_npz(out / "dataset.npz"))
    if "paper" in formats:
        if scene.sensor is Sensor.NUSKIN:
            written += write_tact(arrays, out / "nuskin", scene.trial_s)
        else:
            written.append(write_biotac_csv(arrays, out / "biotac" / "biotac.csv"))
    if "raw" in formats and batches and "wire" in batches[0][1]:
        streams = [s for _, signals in batches for s in signals["wire"]]
        trial_ns = round(scene.trial_s * 1e9)
        written += write_raw(streams, scene.sensor.label, out / "raw", trial_ns)
    if "bag" in formats:
        try:
            from ext_sense_sim.output.bag import write_bag

            written += write_bag(arrays, out / "bag")
        except ModuleNotFoundError as err:
            if err.name != "ext_sense_bags":
                raise
    return written
