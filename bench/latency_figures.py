"""The latency benchmark's pure parts (``bench_runtime.py``): the synthetic tap stream as the
driver's packets, the nodes' own work replayed on it, the split into hops, the printed lines."""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np
from common import pct

from ext_sense_runtime.records import EventBlock
from ext_sense_runtime.stamps import MS

READS_PER_MS = 4
"""Reads per 1 ms drain in the packet stream: the driver's reader returns as bytes arrive."""
BAUD = 4_000_000
"""The graphs' NUSkin link rate (the packets' ``baud`` option, as the driver sets it)."""
IDLE_WORDS_PER_S = 540.0
"""Background words/s: a powered NUSkin receiver's idle stream (``ext_sense_drivers.liveness``)."""


class Batch(NamedTuple):
    """One 1 ms batch of the synthetic stream: its start from the stream's, and its events."""

    stamp_ns: int
    events: EventBlock  # t_ns: offset from the batch's stamp


def tap_batches(
    onsets_ms: list[float],
    duration_ms: float,
    *,
    rate_hz: float = 4000.0,
    taxels: int = 80,
    burst_ms: float = 40.0,
    noise_per_s: float = IDLE_WORDS_PER_S,
    seed: int = 7,
) -> list[Batch]:
    """1 ms batches of NUSkin events: background noise plus a burst of ``taxels`` at each onset.

    During a burst every taxel fires at ``rate_hz`` (the 80-taxel, 4 kHz worst case).
    """
    rng = np.random.default_rng(seed)
    n_noise = rng.poisson(noise_per_s * duration_ms / 1000)
    times = [rng.integers(0, int(duration_ms * MS), n_noise)]
    tax = [rng.integers(1, 81, n_noise)]
    period = int(1e9 / rate_hz)
    for onset in onsets_ms:
        start = int(onset * MS)
        ticks = np.arange(start, start + int(burst_ms * MS), period)
        times.append(np.repeat(ticks, taxels))
        tax.append(np.tile(np.arange(1, taxels + 1), len(ticks)))
    t = np.concatenate(times).astype(np.int64)
    order = np.argsort(t, kind="stable")
    t, k = t[order], np.concatenate(tax)[order]
    pol = np.where(rng.random(len(t)) < 0.5, 1, -1)
    val = rng.integers(0, 1024, len(t))
    everything = EventBlock.of(t, k, pol, val)
    edges = np.searchsorted(t, np.arange(0, int(duration_ms * MS) + MS, MS))
    out = []
    for i in range(len(edges) - 1):
        block = everything.select(slice(edges[i], edges[i + 1]))
        out.append(Batch(i * MS, block._replace(t_ns=block.t_ns - i * MS)))
    return out


def batch_reads(batch: Batch) -> list[tuple[int, bytes]]:
    """A batch as the driver's reader would have read it: ``(return offset ns, words)`` for
    each of the ms's :data:`READS_PER_MS` parts holding events."""
    from ext_sense_drivers.nuskin.wire import encode_words

    ev, step = batch.events, MS // READS_PER_MS
    edges = np.searchsorted(ev.t_ns, np.arange(0, MS + 1, step), side="left")
    return [
        ((i + 1) * step, encode_words(ev.taxel[lo:hi], ev.value[lo:hi]))
        for i, (lo, hi) in enumerate(zip(edges[:-1].tolist(), edges[1:].tolist(), strict=True))
        if hi > lo
    ]


class Source:
    """The bench as the sensor driver: each 1 ms drain's ``SensorPacket``, built when due.

    With ``nuskin_driver``'s packer and message code, and its "nothing read" packet every
    ``quiet_s`` (``quiet_packets_period_s``) while nothing is read.
    """

    def __init__(self, batches: list[Batch], quiet_s: float | None = None) -> None:
        from ext_sense.topics import SENSOR_PACKETS
        from ext_sense_drivers.nodes.nuskin_driver import packet_encoding
        from ext_sense_drivers.nuskin.driver_config import DriverConfig
        from ext_sense_drivers.packets import QUIET_PACKETS_PERIOD_S, PacketPacker, QuietSchedule
        from ext_sense_msgs.msg import SensorPacket

        self.quiet_s = QUIET_PACKETS_PERIOD_S if quiet_s is None else quiet_s
        self.type, self.topic = SensorPacket, SENSOR_PACKETS["nuskin"]
        self.packer = PacketPacker(*packet_encoding(DriverConfig(baud=BAUD)))
        self.reads = [batch_reads(b) for b in batches]
        self.quiet = QuietSchedule(self.quiet_s)

    def messages(self, i: int, stamp_ns: int) -> list[tuple[Any, int]]:
        """Batch ``i`` (starting at wall ``stamp_ns``): ``(message, stream time it completes)``."""
        from ext_sense_drivers.nodes.link_node import packet_message
        from ext_sense_drivers.transports.base import Chunk

        chunks = [(1, Chunk(data, stamp_ns + t)) for t, data in self.reads[i]]
        packets = self.packer.pack(chunks, False)
        drain_ns = stamp_ns + MS  # the driver drains at the end of the ms
        if chunks:
            self.quiet.on_bytes(drain_ns)
        elif self.quiet.due(drain_ns):  # the driver's quiet timer: nothing read, it says so
            packets = [self.packer.nothing_read(drain_ns)]
        return [(packet_message(p, "nuskin"), p.end_ns) for p in packets]


class NodeWork(NamedTuple):
    """Per final window, ms, measured here on the same stream.

    ``cut``: the window node's decode and cut of the input that closed it; ``compute``: the
    model's features + ONNX Runtime on it.
    """

    cut: list[float]
    compute: list[float]


def node_work(model_dir: Path, inputs: list[Any]) -> NodeWork:
    """The nodes' own work per final window, replayed here on the run's ``SensorPacket``s
    through the window node's core (``WindowStage``) and the model (after three warm-ups)."""
    from ext_sense_perception.online.model_card import read_card
    from ext_sense_perception.online.predictor import load_model
    from ext_sense_perception.online.stage import WindowStage
    from ext_sense_perception.online.window import WindowConfig
    from ext_sense_runtime.enums import Sensor

    card = read_card(model_dir)
    stage = WindowStage(WindowConfig.for_profile(card.profile, Sensor.NUSKIN))
    finals, cut = [], []
    for item in inputs:
        t0 = time.perf_counter_ns()
        windows = stage.on_packet(item)
        spent = (time.perf_counter_ns() - t0) / MS
        done = [w for w in windows if not w.provisional]
        finals += done
        cut += [spent] * len(done)
    model = load_model(model_dir, "onnx", card.task, "nuskin")
    for w in finals[:3]:
        model.predict(w)
    compute = []
    for w in finals:
        t0 = time.perf_counter_ns()
        model.predict(w)
        compute.append((time.perf_counter_ns() - t0) / MS)
    return NodeWork(cut, compute)


class Final(NamedTuple):
    """One final estimate as the bench saw it, wall ns (the driver's clock).

    Window end (onset + post-onset time), the window at the bench's subscriber, the estimate
    ready (``end_ns`` + its ``compute_latency``) and at the bench.
    """

    end_ns: int
    window_received_ns: int
    ready_ns: int
    received_ns: int


def hops(finals: list[Final], published: list[tuple[int, int]]) -> dict[str, object]:
    """Split window end -> estimate received into its hops (p50, p99 ms each).

    ``published``: ``(publish wall ns, stream time the input completes)`` of every input
    message. Hops: ``wait`` (window end -> the first input past it published), ``window_node``
    (-> window received), ``window`` (window end -> window received, every window),
    ``inference`` (-> estimate ready) and ``estimate`` (-> received); and the share of windows
    the deadline timer closed.
    """
    pub = np.asarray([p for p, _ in published], np.int64)
    done = np.maximum.accumulate(np.asarray([c for _, c in published], np.int64))
    parts: dict[str, list[float]] = {
        k: [] for k in ("wait", "window_node", "window", "inference", "estimate")
    }
    by_deadline = 0
    for f in finals:
        i = int(np.searchsorted(done, f.end_ns, side="left"))
        closer = int(pub[i]) if i < pub.size else None
        if closer is None or closer > f.window_received_ns:
            by_deadline += 1
        else:
            parts["wait"].append((closer - f.end_ns) / MS)
            parts["window_node"].append((f.window_received_ns - closer) / MS)
        parts["window"].append((f.window_received_ns - f.end_ns) / MS)
        parts["inference"].append((f.ready_ns - f.window_received_ns) / MS)
        parts["estimate"].append((f.received_ns - f.ready_ns) / MS)
    out: dict[str, object] = {k: pct(v) for k, v in parts.items()}
    out["closed_by_deadline"] = f"{by_deadline} of {len(finals)}"
    return out


def print_latency(r: dict, taps: int) -> None:
    """The latency lines of one run, the issue's one (``window end -> estimate received``)."""
    tag = f"[latency {r['tree']}, {r['input']}, {r['load']}, hot_path:={r['hot_path']}]"
    print(
        f"{tag} model: {r['model']}: {r['model_id']} ({r['model_kind']}); "
        f"{r['final_estimates']} final + {r['provisional_estimates']} provisional "
        f"estimates for {taps} taps; load average {r['load_average_1min']:.2f} "
        f"(before the run {r['load_average_before']:.2f})"
    )
    print(
        f"{tag} window end -> estimate received: p50 "
        f"{r['window_end_to_estimate_received_p50_ms']:.2f} ms, p99 "
        f"{r['window_end_to_estimate_received_p99_ms']:.2f} ms; "
        f"model compute (features + ONNX, one window): p50 {r['model_compute_p50_ms']:.2f} ms, "
        f"p99 {r['model_compute_p99_ms']:.2f} ms (targets: p50 <= compute + 1 = "
        f"{r['target_p50_ms']:.2f} ms, p99 <= {r['target_p99_ms']:.0f} ms); node's "
        f"compute_latency p50 {r['compute_latency_field_p50_ms']:.2f} ms, p99 "
        f"{r['compute_latency_field_p99_ms']:.2f} ms"
    )
    print(
        f"{tag} window node's core on the input that closed a window (this tree's code, "
        f"replayed here): p50 "
        f"{r['cut_p50_ms']:.2f} ms, p99 {r['cut_p99_ms']:.2f} ms; slowest compute_latency "
        f"(ms, tap): {r['slowest_taps_ms']}",
        flush=True,
    )
    if "hops" in r:
        h = r["hops"]
        spans = ", ".join(
            f"{k} {h[k][0]:.2f} / {h[k][1]:.2f}"
            for k in ("wait", "window_node", "window", "inference", "estimate")
        )
        print(
            f"{tag} hops p50 / p99 ms: {spans}; closed by the deadline timer: "
            f"{h['closed_by_deadline']}",
            flush=True,
        )


def print_table(results: list[dict]) -> None:
    """Every latency run side by side: one row each."""
    print("[latency] side by side: tree | input | load | hot_path | p50 | p99 | compute p50 | load")
    for r in results:
        print(
            f"[latency] {r['tree']} | {r['input']} | {r['load']} | {r['hot_path']} | "
            f"{r['window_end_to_estimate_received_p50_ms']:.2f} ms | "
            f"{r['window_end_to_estimate_received_p99_ms']:.2f} ms | "
            f"{r['model_compute_p50_ms']:.2f} ms | {r['load_average_before']:.2f}",
            flush=True,
        )
