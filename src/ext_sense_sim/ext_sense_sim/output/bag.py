"""A run's rosbag2 bag: the packets the drivers would have published, and the ground truth.

Trials lie ``trial_period_ns`` apart from ``t0_ns`` (by default back to back from the paper
formats' epoch); each trial's truth is stamped at its onset and logged at its origin, before its
data, as the live simulator sends it. NUSkin events become receiver words, one read per distinct
event time and one packet per ``batch_ns``, with the driver's "nothing read" packets between and
the stream's end after the last trial; a BioTac frame of 22 PAC samples becomes one bridge frame
arriving the driver's clock lead after its first sample. ``ext-sense bag migrate`` encodes the
decoded arrays of older bags with the same :class:`NuskinPackets` and :func:`frame_packets`.
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping
from pathlib import Path

import numpy as np
from ext_sense_bags.messages import sensor_packet

from ext_sense_bags import BagWriter, ground_truth
from ext_sense_drivers.biotac.clock import FRAME_PERIOD_NS, PAC_PERIOD_NS, transmission_ns
from ext_sense_drivers.biotac.encoder import encode_standard_frame
from ext_sense_drivers.biotac.frame_layout import SEQ_MODULO, STANDARD_FRAME_SIZE
from ext_sense_drivers.biotac.words import N_PAC
from ext_sense_drivers.nuskin.wire import encode_words
from ext_sense_drivers.packets import (
    BIOTAC_BRIDGE_V1,
    NUSKIN_WORDS_V1,
    QUIET_PACKETS_PERIOD_S,
    Packet,
    PacketPacker,
    format_options,
)
from ext_sense_drivers.transports.base import Chunk
from ext_sense_sim.output.paper import BASE_EPOCH_S

NUSKIN_PACKETS = "/extsense/nuskin/packets"
BIOTAC_PACKETS = "/extsense/biotac/packets"
TRUTH = "/extsense/ground_truth"
NUSKIN_BAUD = 4_000_000
BIOTAC_BAUD = 1_000_000
BIOTAC_LEAD_NS = FRAME_PERIOD_NS + transmission_ns(STANDARD_FRAME_SIZE, BIOTAC_BAUD)
"""The BioTac driver's default clock lead (a serial bridge at its default baud)."""
FRAME_NS = N_PAC * PAC_PERIOD_NS
"""A frame's 22 samples at the message's sample period (9_999_990 ns)."""
QUIET_NS = round(QUIET_PACKETS_PERIOD_S * 1e9)
CONNECTION = 1


class NuskinPackets:
    """The NUSkin driver's packets of batches of events, "nothing read" between them.

    ``signed``: the words' flag bit carries the polarity; ``start_ns``: the link opened.
    """

    def __init__(self, signed: bool, start_ns: int) -> None:
        flag = "is_positive" if signed else "ignore"
        options = format_options({"baud": NUSKIN_BAUD, "flag_polarity": flag})
        self.packer = PacketPacker(NUSKIN_WORDS_V1, options)
        self.start_ns = start_ns
        self.last_ns: int | None = None

    def batch(
        self, t: np.ndarray, taxel: np.ndarray, value: np.ndarray, flag: np.ndarray
    ) -> list[Packet]:
        """The packets of one batch of ``(n,)`` events: the silence before it, then its reads."""
        if not t.size:
            return []
        order = np.argsort(t, kind="stable")
        t, taxel, value, flag = t[order], taxel[order], value[order], flag[order]
        out = [] if self.last_ns is None else list(self._quiet(self.last_ns, int(t[0])))
        if self.last_ns is None:
            opened = self.packer.opened(CONNECTION, min(self.start_ns, int(t[0])))
            out += [] if opened is None else [opened]
        cuts = np.flatnonzero(np.diff(t)) + 1
        reads = [
            (CONNECTION, Chunk(encode_words(k, v, f), int(ts[-1])))
            for k, v, f, ts in zip(
                *(np.split(a, cuts) for a in (taxel, value, flag, t)), strict=True
            )
        ]
        out += self.packer.pack(reads, link_down=False)
        self.last_ns = max(int(t[-1]), self.last_ns or 0)
        return out

    def _quiet(self, from_ns: int, to_ns: int) -> Iterator[Packet]:
        """The driver's "nothing read" packets between two reads."""
        for t in range(from_ns + QUIET_NS, to_ns, QUIET_NS):
            packet = self.packer.nothing_read(t)
            if packet is not None:
                yield packet

    def finish(self, end_ns: int) -> list[Packet]:
        """The silence up to ``end_ns``, then the end of the stream."""
        if self.last_ns is None:
            return []
        out = list(self._quiet(self.last_ns, max(end_ns, self.last_ns) + QUIET_NS))
        return out + self.packer.pack([], link_down=True)


def biotac_packer() -> PacketPacker:
    """The BioTac driver's packer with its default clock settings."""
    options = format_options({"clock_window_frames": 200, "lead_ns": BIOTAC_LEAD_NS})
    return PacketPacker(BIOTAC_BRIDGE_V1, options)


def frame_packets(
    packer: PacketPacker,
    stamp_ns: int,
    seq: int,
    sensor_id: int,
    pac: np.ndarray,
    electrodes: np.ndarray,
    pdc: int,
    tac: int,
    tdc: int,
) -> list[Packet]:
    """One frame (first sample at ``stamp_ns``) as the bridge frame a driver reads, one packet.

    ``pac`` ``(22,)`` and ``electrodes`` ``(19,)``; ``seq`` wraps as the bridge's does.
    """
    data = encode_standard_frame(seq % SEQ_MODULO, sensor_id, pac, electrodes, pdc, tac, tdc)
    return packer.pack([(CONNECTION, Chunk(data, stamp_ns + BIOTAC_LEAD_NS))], link_down=False)


def write_bag(
    arrays: Mapping[str, np.ndarray],
    out: str | Path,
    *,
    t0_ns: int = round(BASE_EPOCH_S * 1e9),
    trial_period_ns: int | None = None,
    batch_ns: int = 1_000_000,
    trials: int | None = None,
    storage: str = "mcap",
) -> list[Path]:
    """Write a simulator dataset's packet bag into the new directory ``out``.

    Args:
        arrays: The dataset's arrays (docs/conventions.md), e.g. ``np.load("dataset.npz")``.
        out: Directory of the new bag.
        t0_ns: Host time of trial 0's origin, ns.
        trial_period_ns: Time between trial origins, ns (default: the dataset's ``trial_ns``).
        batch_ns: NUSkin packet length, ns (the driver's default drain).
        trials: Only the first ``trials`` trials (all when None).
        storage: ``"mcap"`` or ``"sqlite3"``.

    Returns:
        The files written.
    """
    d = dict(arrays)
    task, nuskin = str(d["task"]), str(d["sensor"]) == "nuskin"
    trial_ns = int(d["trial_ns"])
    period = trial_ns if trial_period_ns is None else trial_period_ns
    n = len(d["y"]) if trials is None else min(trials, len(d["y"]))
    regression = str(d["label_kind"]) == "regression"
    topic = NUSKIN_PACKETS if nuskin else BIOTAC_PACKETS
    stream = NuskinPackets(bool(np.any(d["ev_polarity"] != 0)), t0_ns) if nuskin else None
    packer = None if nuskin else biotac_packer()
    with BagWriter(out, storage) as bag:
        bag.set_custom_data("task", task)
        bag.set_custom_data("sensor", str(d["sensor"]))
        for i in range(n):
            origin = t0_ns + i * period
            y = d["y"][i]
            truth = ground_truth(
                origin + int(d["onset_ns"][i]),
                task,
                i,
                tap_position_m=float(y) if regression else float("nan"),
                rod_length_m=float(d["rod_length_m"][i]),
                class_label="" if regression else str(y),
            )
            bag.write(TRUTH, origin, truth)
            if stream is not None:
                packets = list(_trial_events(stream, d, i, origin, batch_ns))
                # after the last trial: the silence to its end, then the stream's end
                packets += stream.finish(origin + trial_ns) if i == n - 1 else []
            else:
                packets = _trial_frames(packer, d, i, origin)
            for packet in packets:
                bag.write(topic, packet.end_ns, sensor_packet(packet))
    return sorted(p for p in Path(out).rglob("*") if p.is_file())


def _trial_events(
    stream: NuskinPackets, d: dict, i: int, origin: int, batch_ns: int
) -> Iterator[Packet]:
    """Trial ``i``'s events in packets of ``batch_ns`` from its origin."""
    sel = d["ev_trial"] == i
    t = d["ev_t_ns"][sel].astype(np.int64)
    order = np.argsort(t, kind="stable")
    t = t[order]
    taxel, value = (d[k][sel][order].astype(np.int64) for k in ("ev_taxel", "ev_value"))
    flag = (d["ev_polarity"][sel][order] > 0).astype(np.int64)
    cuts = np.flatnonzero(np.diff(t // batch_ns)) + 1
    for part in zip(*(np.split(a, cuts) for a in (t + origin, taxel, value, flag)), strict=True):
        yield from stream.batch(*part)


def _trial_frames(packer: PacketPacker, d: dict, i: int, origin: int) -> Iterator[Packet]:
    """Trial ``i``'s frames, both sensors' in turn, each frame carrying its 100 Hz sample."""
    pac = d["pac"][i]  # (n_sensors, n_samples)
    t0 = origin + int(d["pac_t0_ns"][i])
    last = d["pdc"].shape[2] - 1
    for f in range(pac.shape[1] // N_PAC):
        j = min(f, last)
        for s in range(pac.shape[0]):
            yield from frame_packets(
                packer,
                t0 + f * FRAME_NS,
                f,
                s,
                pac[s, f * N_PAC : (f + 1) * N_PAC],
                d["electrodes"][i, s, j],
                int(d["pdc"][i, s, j]),
                int(d["tac"][i, s, j]),
                int(d["tdc"][i, s, j]),
            )
