"""Synthetic tap streams and a stand-in model for runtime tests (no simulator, no training)."""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from ext_sense_runtime.stamps import MS

T0 = 1_700_000_000_000_000_000


class Batch(NamedTuple):
    """One 1 ms batch of events: stamp and parallel arrays."""

    stamp_ns: int
    taxel: np.ndarray
    polarity: np.ndarray
    value: np.ndarray
    offset_ns: np.ndarray


def tap_stream(
    onsets_ms: list[float],
    duration_ms: float,
    *,
    t0_ns: int = T0,
    rate_hz: float = 4000.0,
    taxels: int = 80,
    burst_ms: float = 40.0,
    noise_per_s: float = 50.0,
    seed: int = 0,
) -> list[Batch]:
    """1 ms batches of NUSkin events: background noise plus a burst of ``taxels`` at each onset.

    During a burst every taxel fires at ``rate_hz`` (the 80-taxel, 4 kHz worst case).
    """
    rng = np.random.default_rng(seed)
    times, tax = [], []
    n_noise = rng.poisson(noise_per_s * duration_ms / 1000)
    times.append(rng.integers(0, int(duration_ms * MS), n_noise))
    tax.append(rng.integers(1, 81, n_noise))
    period = int(1e9 / rate_hz)
    for onset in onsets_ms:
        start = int(onset * MS)
        ticks = np.arange(start, start + int(burst_ms * MS), period)
        times.append(np.repeat(ticks, taxels))
        tax.append(np.tile(np.arange(1, taxels + 1), len(ticks)))
    t = np.concatenate(times).astype(np.int64)
    k = np.concatenate(tax).astype(np.uint16)
    order = np.argsort(t, kind="stable")
    t, k = t[order], k[order]
    pol = np.where(rng.random(len(t)) < 0.5, 1, -1).astype(np.int8)
    val = rng.integers(0, 1024, len(t)).astype(np.uint16)
    out = []
    edges = np.searchsorted(t, np.arange(0, int(duration_ms * MS) + MS, MS))
    for i in range(len(edges) - 1):
        lo, hi = edges[i], edges[i + 1]
        stamp = t0_ns + i * MS
        out.append(Batch(stamp, k[lo:hi], pol[lo:hi], val[lo:hi], t[lo:hi] - i * MS))
    return out


def event_batch_msg(batch: Batch, stamp_ns: int | None = None):
    """The rclpy ``TaxelEventBatch`` of a synthetic batch (stamp: ``stamp_ns``, else its own)."""
    from ext_sense_msgs.msg import TaxelEventBatch
    from ext_sense_runtime.stamps import fill_stamp

    msg = TaxelEventBatch()
    fill_stamp(msg.header.stamp, batch.stamp_ns if stamp_ns is None else stamp_ns)
    msg.taxel, msg.polarity = batch.taxel, batch.polarity
    msg.value, msg.offset_ns = batch.value, batch.offset_ns
    return msg


WORDS_OPTIONS = "baud=4000000;flag_polarity=ignore"
"""The NUSkin driver's packet options at its defaults."""


def stream_packets(batches: list[Batch], connection: int = 1, packer=None) -> list:
    """The NUSkin driver's packets of a synthetic stream (``Packet`` records, no ROS).

    The link opens at the first batch's stamp (``PacketPacker.opened``, unless ``packer``, a
    driver's packer to go on with, has that connection going); a batch with events is one
    packet of a read per distinct event time, returning then with the events' receiver words
    (flag 0, as real receivers send: each decodes within its transmission time of its time),
    and a batch without is the driver's "nothing read" packet at the batch's end.
    """
    from ext_sense_drivers.nuskin.wire import encode_words
    from ext_sense_drivers.packets import NUSKIN_WORDS_V1, PacketPacker
    from ext_sense_drivers.transports.base import Chunk

    packer = PacketPacker(NUSKIN_WORDS_V1, WORDS_OPTIONS) if packer is None else packer
    out = [p for p in [packer.opened(connection, batches[0].stamp_ns)] if p is not None]
    for b in batches:
        if not b.taxel.size:
            out.append(packer.nothing_read(b.stamp_ns + MS))
            continue
        t = np.asarray(b.offset_ns, np.int64) + np.int64(b.stamp_ns)
        order = np.argsort(t, kind="stable")
        t, taxel, value = t[order], np.asarray(b.taxel)[order], np.asarray(b.value)[order]
        cuts = np.flatnonzero(np.diff(t)) + 1
        reads = [
            (connection, Chunk(encode_words(k, v), int(ts[-1])))
            for k, v, ts in zip(
                np.split(taxel, cuts), np.split(value, cuts), np.split(t, cuts), strict=True
            )
        ]
        out += packer.pack(reads, link_down=False)
    return out


class CountingModel:
    """Stand-in for a tap model bundle: position = events in the window / 1e6 m; NaN rejected.

    It has the bundle's interface (``task``, ``card.sensor``, ``card.profile``, ``model_id``,
    ``predict``), so the nodes and the offline replay take it as they take a loaded bundle.
    """

    model_id = "counting-test-model"
    task = "tap_localization"

    def __init__(self) -> None:
        from types import SimpleNamespace

        from ext_sense_perception.profiles import profile_for

        self.card = SimpleNamespace(sensor="nuskin", profile=profile_for(self.task))

    def predict(self, window):
        from ext_sense_perception.errors import PerceptionError
        from ext_sense_runtime.records import Estimate

        data = np.asarray(window.data)
        if not np.isfinite(data).all():
            raise PerceptionError("The window holds NaN or inf.")
        return Estimate(
            task=window.task,
            onset_ns=window.onset_ns,
            sensor=window.sensor,
            model_id=self.model_id,
            provisional=window.provisional,
            post_contact_used_ns=window.post_onset_ns,
            tap_position_m=float(np.abs(data).sum()) / 1e6,
            tap_position_std_m=0.01,
        )
