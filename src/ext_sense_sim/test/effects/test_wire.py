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


def test_biotac_wire_numbers_each_sensors_frames_as_the_bridge_does():
    """Per sensor, +1 per frame (docs/biotac_bridge.md): the two fingers' frames of one step
    share a number (the window node joins them by it) and the driver counts no lost frame."""
    from ext_sense_drivers.biotac.decoder import BridgeDecoder
    from ext_sense_sim.engine import Simulator
    from ext_sense_sim.scene import load_scene

    sim = Simulator(load_scene("handover_plate_biotac"))
    data = b""
    for _, sig in sim.batches(30, 0):  # two batches (25 + 5): numbering runs on across them
        data += b"".join(chunk for stream in sig["wire"] for _, chunk in stream.chunks())
    decoder = BridgeDecoder()
    frames = decoder.feed(data)
    assert frames.seq.size == 2 * 30 * 29  # sensors x trials x frames per trial
    assert np.array_equal(frames.seq[0::2], frames.seq[1::2])
    assert np.array_equal(frames.sensor_id[0::2], np.zeros(frames.seq.size // 2))
    assert np.array_equal(
        np.diff(frames.seq[0::2].astype(np.int64)), np.ones(frames.seq.size // 2 - 1)
    )
    assert sum(decoder.counters.dropped_frames) == 0
