"""``ext-sense plot`` on a bag (written here with the ext_sense_bags writer: a tap stream, its
ground truth and final estimates) and on a folder of real captures (skipped when absent)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from sim_models import cli
from synthetic import T0, stream_packets, tap_stream

from ext_sense_runtime.stamps import MS

ONSETS_MS = [200.0, 900.0, 1600.0]
TRUE_M = [0.05, 0.15, 0.25]


def _tap_bag(path: Path) -> Path:
    from ext_sense_bags.messages import (
        duration,
        ground_truth,
        header,
        make_message,
        sensor_packet,
    )
    from ext_sense_bags.writer import BagWriter

    with BagWriter(path) as bag:
        for p in stream_packets(tap_stream(ONSETS_MS, 2000, taxels=20, burst_ms=30)):
            bag.write("/extsense/nuskin/packets", p.end_ns, sensor_packet(p, "nuskin"))
        for k, (onset, true_m) in enumerate(zip(ONSETS_MS, TRUE_M, strict=True)):
            stamp = T0 + int(onset * MS)
            truth = ground_truth(
                stamp, "tap_localization", k, tap_position_m=true_m, rod_length_m=0.3
            )
            bag.write("/extsense/ground_truth", stamp, truth)
            est = make_message(
                "ext_sense_msgs/msg/ContactEstimate",
                header=header(stamp),
                task="tap_localization",
                sensor="nuskin",
                compute_latency=duration(5 * MS),
                tap_position_m=true_m + 0.01,
                tap_position_std_m=0.02,
                class_index=-1,
                stability_probability=float("nan"),
            )
            bag.write("/extsense/contact_estimate", stamp + 300 * MS, est)
    return path


def _tap_packet_bag(path: Path) -> tuple[Path, int]:
    """The same taps as the driver records them by default: receiver words in raw packets,
    one per 1 ms batch, and no decoded arrays. Returns the bag and its events."""
    from ext_sense_bags.messages import sensor_packet
    from ext_sense_bags.writer import BagWriter

    from ext_sense_drivers.nuskin.wire import encode_words
    from ext_sense_drivers.packets import NUSKIN_WORDS_V1, PacketPacker
    from ext_sense_drivers.transports.base import Chunk

    packer = PacketPacker(NUSKIN_WORDS_V1)
    events = 0
    with BagWriter(path) as bag:
        for b in tap_stream(ONSETS_MS, 2000, taxels=20, burst_ms=30):
            chunk = Chunk(encode_words(b.taxel, b.value), b.stamp_ns + MS)
            for p in packer.pack([(1, chunk)], link_down=False):
                msg = sensor_packet(p, "nuskin")
                bag.write("/extsense/nuskin/packets", p.stamp_ns, msg)
            events += len(b.taxel)
        for k, onset in enumerate(ONSETS_MS):
            stamp = T0 + int(onset * MS)
            bag.write("/extsense/ground_truth", stamp, _truth(stamp, k))
    return path, events


def _truth(stamp: int, k: int):
    from ext_sense_bags.messages import ground_truth

    return ground_truth(stamp, "tap_localization", k, tap_position_m=TRUE_M[k], rod_length_m=0.3)


def test_plot_a_packet_bag_decodes_the_drivers_bytes(tmp_path: Path) -> None:
    """A bag recorded by default holds raw packets only: plotted from them, every event kept."""
    from ext_sense.view.sessions import load_session

    bag, events = _tap_packet_bag(tmp_path / "packets")
    session = load_session(bag)
    assert session.sensor == "nuskin"
    assert len(session.events.t_ns) == events
    assert [c.truth.trial for c in session.contacts] == [0, 1, 2]
    out = cli("plot", str(bag), "--out", str(tmp_path / "png"), timeout=120)
    assert out.returncode == 0, out.stdout + out.stderr
    assert "3 contacts" in out.stdout


def _png_size(path: Path) -> tuple[int, int]:
    head = path.read_bytes()[:24]
    assert head[:8] == b"\x89PNG\r\n\x1a\n", path
    return int.from_bytes(head[16:20], "big"), int.from_bytes(head[20:24], "big")


def test_plot_a_bag_draws_the_overview_and_each_contact(tmp_path: Path) -> None:
    from ext_sense.view.sessions import load_session

    bag = _tap_bag(tmp_path / "taps")
    session = load_session(bag)
    assert session.task == "tap_localization"
    assert [c.truth.trial for c in session.contacts] == [0, 1, 2]
    assert all(c.estimate is not None for c in session.contacts)
    assert session.contacts[1].estimate.tap_position_m == pytest.approx(0.16)
    out = cli("plot", str(bag), "--out", str(tmp_path / "png"), timeout=120)
    assert out.returncode == 0, out.stdout + out.stderr
    names = sorted(p.name for p in (tmp_path / "png").iterdir())
    assert names == ["contact_001.png", "contact_002.png", "contact_003.png", "overview.png"]
    width, height = _png_size(tmp_path / "png" / "overview.png")
    assert width > 800
    assert height > 400
    assert "3 contacts" in out.stdout


def test_plot_refuses_what_it_cannot_read(tmp_path: Path) -> None:
    from ext_sense_bags.messages import taxel_event_batch
    from ext_sense_bags.writer import BagWriter

    from ext_sense.view.errors import ViewError
    from ext_sense.view.sessions import load_session

    out = cli("plot", str(tmp_path / "absent"), timeout=60)
    assert out.returncode == 2
    assert "no such file or directory" in out.stdout
    with BagWriter(tmp_path / "old") as bag:  # decoded arrays, from before packets
        bag.write("/extsense/nuskin/events", T0, taxel_event_batch(T0, [3], [0], [9], [0]))
    with pytest.raises(ViewError, match="ext-sense bag migrate"):
        load_session(tmp_path / "old")


@pytest.mark.real_data
def test_plot_a_real_capture_folder(food_poking_dir: Path, tmp_path: Path) -> None:
    from ext_sense.view.figures import rate_map
    from ext_sense.view.sessions import load_session

    session = load_session(food_poking_dir)
    assert session.task == "food_identification"
    assert len(session.contacts) >= 40  # the 44 labelled trials of 1 April
    assert {c.truth.class_label for c in session.contacts} >= {"water", "tofu"}
    rates, _, _ = rate_map(session)
    assert rates.shape[0] == 80
    assert np.count_nonzero(rates.sum(axis=1)) > 60  # most taxels fire over the session
    out = cli("plot", str(food_poking_dir), "--out", str(tmp_path), "--max-contacts", "2")
    assert out.returncode == 0, out.stdout + out.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == [
        "contact_001.png",
        "contact_002.png",
        "overview.png",
    ]
