import numpy as np
import pytest

from ext_sense_sim.errors import SceneError
from ext_sense_sim.food_stats import read_tact, real_stats, sim_stats, table


@pytest.mark.real_data
def test_real_captures_are_read_and_summarised(food_poking_dir):
    stats = real_stats(food_poking_dir)
    assert len(stats) == 45
    rows = table(stats)
    assert set(rows) == {"apple", "empty", "tofu", "water", "watermelon"}
    for rate, active, p5, p50, p95 in rows.values():
        assert 300 < rate < 1500
        assert 50 < active <= 80
        assert 0 <= p5 <= p50 <= p95 <= 1023


def test_tact_reader_drops_markers_and_rejects_bad_files(tmp_path):
    good = tmp_path / "a_zero_0.tact"
    good.write_text("1 1 1 10.00\n0 5 100 10.01\n0 45 200 10.02\n2 2 2 10.03\n")
    taxel, value, t = read_tact(good)
    assert taxel.tolist() == [5, 45]
    assert value.tolist() == [100, 200]
    np.testing.assert_allclose(t, [10.01, 10.02])
    bad = tmp_path / "b_zero_0.tact"
    bad.write_text("1 2 3\n")
    with pytest.raises(SceneError, match="4 columns"):
        read_tact(bad)


def test_sim_stats_per_trial():
    arrays = {
        "trial": np.arange(2, dtype=np.int32),
        "y": np.array(["apple", "water"]),
        "ev_trial": np.array([0, 0, 1], np.int32),
        "ev_taxel": np.array([3, 3, 9], np.uint16),
        "ev_value": np.array([10, 20, 30], np.uint16),
    }
    s = sim_stats(arrays, trial_s=2.0)
    assert [x.events_per_s for x in s] == [1.0, 0.5]
    assert [x.active_taxels for x in s] == [1, 1]


@pytest.mark.real_data
def test_simulated_food_event_statistics_are_near_the_real_captures(food_poking_dir):
    # Calibration check of the shipped food scene (docs/simulator.md): events per second
    # within a factor of two of the real captures per class, hard foods above soft ones, and
    # not every taxel active in every trial.
    from ext_sense_sim.dataset import DatasetCollector
    from ext_sense_sim.engine import Simulator
    from ext_sense_sim.scene import load_scene

    scene = load_scene("food_fork_nuskin")
    collector = DatasetCollector(scene, scene.seed)
    for tb, signals in Simulator(scene).batches(7, scene.seed):
        collector.add(tb, signals)
    sim = table(sim_stats(collector.arrays(), scene.trial_s))
    real = table(real_stats(food_poking_dir))
    for label in real:
        assert 0.5 < sim[label][0] / real[label][0] < 2.0, (label, sim[label], real[label])
    assert min(sim["apple"][0], sim["watermelon"][0]) > max(sim["water"][0], sim["empty"][0])
    assert np.mean([row[1] for row in sim.values()]) < 80
