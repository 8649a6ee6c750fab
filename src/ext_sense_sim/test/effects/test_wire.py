import numpy as np

from ext_sense_sim.effects.wire import WireStream, inject_faults


def test_wire_faults_rates_and_identity():
    rng = np.random.default_rng(0)
    data = bytes(range(256)) * 400
    stream = WireStream(
        data,
        np.arange(0, len(data) + 1, 4, dtype=np.int64),
        np.arange(len(data) // 4, dtype=np.int64),
    )
    same, counts = inject_faults(stream, 0.0, 0.0, 0.0, rng)
    assert same.data == data
    assert counts == {"lost": 0, "flipped": 0, "extra": 0}
    bad, counts = inject_faults(stream, 0.01, 0.01, 0.01, rng)
    n = len(data)
    for key in counts:
        assert abs(counts[key] - 0.01 * n) < 5 * np.sqrt(0.01 * n)
    assert len(bad.data) == n - counts["lost"] + counts["extra"]
    assert bad.offsets[-1] == len(bad.data)
