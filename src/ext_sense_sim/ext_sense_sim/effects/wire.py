"""The wire: NUSkin receiver words, the ACES line, BioTac bridge frames, and wire faults.

Each on the drivers' own codecs. ``nuskin_wire``: one 4-byte receiver word per event (flag bit
0), written ``latency_s`` after it. ``aces_line``: every event's signature summed onto the
shared line with noise and decoded back, so collisions cost what they really cost (recovered
events take the value of the nearest sent event of their taxel). ``biotac_wire``: one bridge
frame per sensor per 10 ms, at its last PAC sample. ``wire_faults``: each byte lost, flipped or
followed by an extra byte with the given probabilities. ``wire``: a :class:`WireStream` per trial.
"""

from __future__ import annotations

from typing import Any, ClassVar, NamedTuple

import numpy as np

from ext_sense_sim.effects.base import Effect, Signals, TimeBase
from ext_sense_sim.errors import SceneError
from ext_sense_sim.trial_events import by_trial, concat, trial_bounds


class WireStream(NamedTuple):
    """Bytes of one trial: chunk ``i``, ``data[offsets[i]:offsets[i+1]]``, goes at ``t_ns[i]``."""

    data: bytes
    offsets: np.ndarray
    t_ns: np.ndarray

    def chunks(self) -> list[tuple[int, bytes]]:
        """``(t_ns, bytes)`` per chunk."""
        o = self.offsets
        return [(int(t), self.data[o[i] : o[i + 1]]) for i, t in enumerate(self.t_ns)]


def _uniform_stream(data: bytes, unit: int, t_ns: np.ndarray) -> WireStream:
    return WireStream(data, np.arange(t_ns.size + 1, dtype=np.int64) * unit, t_ns.astype(np.int64))


class NuskinWire(Effect):
    """Events to receiver words (see module docstring). Gives ``wire``."""

    name = "nuskin_wire"
    needs = ("events",)
    gives = ("wire",)
    defaults: ClassVar[dict[str, Any]] = {"latency_s": 0.001}

    def run(self, signals: Signals, time: TimeBase, rng: np.random.Generator) -> None:
        """Give one :class:`WireStream` of words per trial."""
        from ext_sense_drivers.nuskin.wire import encode_words

        trial, events = signals.need("events", self.name)
        latency = round(self.scalar("latency_s", 0.0, 1.0) * 1e9)
        bounds = trial_bounds(trial, time.n_trials)
        streams = []
        for i in range(time.n_trials):
            sl = slice(bounds[i], bounds[i + 1])
            data = encode_words(events.taxel[sl], events.value[sl])
            streams.append(_uniform_stream(data, 4, events.t_ns[sl] + latency))
        signals["wire"] = streams


class AcesLine(Effect):
    """Events through the shared ACES line and back (see module docstring)."""

    name = "aces_line"
    needs = ("events",)
    gives = ("events",)
    defaults: ClassVar[dict[str, Any]] = {"noise_std": 0.1, "threshold": 0.5, "max_occupancy": 0.6}

    def setup(self) -> None:
        """Check the parameters and precompute what every batch shares."""
        from ext_sense_drivers.aces.bank import load_bank

        self.bank = load_bank()
        self.sent = 0
        self.recovered = 0

    def run(self, signals: Signals, time: TimeBase, rng: np.random.Generator) -> None:
        """Replace ``events`` by what the receiver decodes from the line."""
        from ext_sense_drivers.aces.decoder import decode_line
        from ext_sense_drivers.aces.encoder import encode_line

        trial, events = signals.need("events", self.name)
        bounds = trial_bounds(trial, time.n_trials)
        parts = []
        for i in range(time.n_trials):
            ev = events.select(np.arange(bounds[i], bounds[i + 1]))
            span = time.n_samples * time.dt * self.bank.sample_rate_hz
            occupancy = ev.t_ns.size * self.bank.n_chips / span
            if occupancy > self.scalar("max_occupancy", 0.0):
                raise SceneError(
                    f"Effect '{self.name}': trial {time.first_trial + i} puts {ev.t_ns.size} "
                    f"events on the line, an occupancy of {occupancy:.2f} signatures per sample "
                    f"(limit 'max_occupancy' = {self.params['max_occupancy']}); the line cannot "
                    f"carry that many. Lower the contact forces or raise the NUSkin threshold."
                )
            line = encode_line(
                ev.t_ns,
                ev.taxel.astype(np.int64),
                ev.polarity.astype(np.int64),
                bank=self.bank,
                noise_std=self.scalar("noise_std", 0.0),
                rng=rng,
            )
            got = decode_line(line.samples, self.bank, threshold=self.scalar("threshold", 0, 1))
            value = np.zeros(got.size, np.uint16)
            for taxel in np.unique(got.taxel):  # value of the nearest sent event of the taxel
                sent = np.flatnonzero(ev.taxel == taxel)
                mine = np.flatnonzero(got.taxel == taxel)
                if sent.size:
                    j = np.clip(np.searchsorted(ev.t_ns[sent], got.t_ns[mine]), 0, sent.size - 1)
                    value[mine] = ev.value[sent[j]]
            parts.append((np.full(got.size, i, np.int32), got._replace(value=value)))
            self.sent += ev.t_ns.size
            self.recovered += got.size
        signals["events"] = by_trial(*concat(parts))


class BiotacWire(Effect):
    """BioTac channels to bridge frames (see module docstring). Gives ``wire``."""

    name = "biotac_wire"
    needs = ("biotac",)
    gives = ("wire",)
    defaults: ClassVar[dict[str, Any]] = {"first_seq": 0}

    def setup(self) -> None:
        """Check the parameters and precompute what every batch shares."""
        self.seq = int(self.scalar("first_seq", 0, 65535))

    def run(self, signals: Signals, time: TimeBase, rng: np.random.Generator) -> None:
        """Give one :class:`WireStream` of frames per trial."""
        from ext_sense_drivers.biotac.encoder import encode_frames
        from ext_sense_drivers.biotac.words import (
            ELECTRODE_POSITIONS,
            PAC_POSITIONS,
            PDC_POSITION,
            TAC_POSITION,
            TDC_POSITION,
            encode_values,
        )

        bt = signals.need("biotac", self.name)
        n_trials, n_sensors, n_frames = bt["pdc"].shape
        values = np.zeros((n_trials, n_frames, n_sensors, 44), dtype=np.int64)
        pac = bt["pac"].reshape(n_trials, n_sensors, n_frames, 22).transpose(0, 2, 1, 3)
        values[..., PAC_POSITIONS] = pac
        values[..., ELECTRODE_POSITIONS] = bt["electrodes"].transpose(0, 2, 1, 3)
        for key, pos in (("pdc", PDC_POSITION), ("tac", TAC_POSITION), ("tdc", TDC_POSITION)):
            values[..., pos] = bt[key].transpose(0, 2, 1)
        replies = encode_values(values.reshape(-1, 44)).reshape(-1, 44)
        n = replies.shape[0]
        # each sensor numbers its frames (+1 per frame): one 10 ms step shares its number
        steps = n_trials * n_frames
        seq = np.repeat((self.seq + np.arange(steps)) % 65536, n_sensors)
        self.seq = int((self.seq + steps) % 65536)
        sensor = np.tile(np.arange(n_sensors), steps)
        data = encode_frames(seq, sensor, replies)
        frame_ns = 10_000_000
        per_trial = n_frames * n_sensors
        size = len(data) // max(n, 1)
        streams = []
        for i in range(n_trials):
            t_end = bt["pac_t0_ns"][i] + (np.arange(n_frames) + 1) * frame_ns
            t_ns = np.repeat(t_end, n_sensors)
            chunk = data[i * per_trial * size : (i + 1) * per_trial * size]
            streams.append(_uniform_stream(chunk, size, t_ns))
        signals["wire"] = streams


def inject_faults(
    stream: WireStream, lost: float, flipped: float, extra: float, rng: np.random.Generator
) -> tuple[WireStream, dict[str, int]]:
    """Lose, flip and add bytes of a stream, keeping each surviving byte in its chunk.

    Returns the faulty stream and the counts ``lost``, ``flipped``, ``extra``.
    """
    arr = np.frombuffer(stream.data, dtype=np.uint8).copy()
    chunk = np.repeat(np.arange(stream.t_ns.size), np.diff(stream.offsets))
    flip = np.flatnonzero(rng.random(arr.size) < flipped)
    arr[flip] ^= (1 << rng.integers(0, 8, size=flip.size)).astype(np.uint8)
    keep = rng.random(arr.size) >= lost
    arr, chunk = arr[keep], chunk[keep]
    add = np.flatnonzero(rng.random(arr.size) < extra)
    arr = np.insert(arr, add + 1, rng.integers(0, 256, size=add.size).astype(np.uint8))
    chunk = np.insert(chunk, add + 1, chunk[add])
    counts = np.bincount(chunk, minlength=stream.t_ns.size)
    offsets = np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)
    counts_out = {"lost": int((~keep).sum()), "flipped": int(flip.size), "extra": int(add.size)}
    return WireStream(arr.tobytes(), offsets, stream.t_ns), counts_out


class WireFaults(Effect):
    """Lost, flipped and extra bytes on the wire (see module docstring)."""

    name = "wire_faults"
    needs = ("wire",)
    gives = ("wire",)
    defaults: ClassVar[dict[str, Any]] = {"lost": 1e-4, "flipped": 1e-4, "extra": 1e-4}

    def setup(self) -> None:
        """Check the parameters and precompute what every batch shares."""
        self.counts = {"lost": 0, "flipped": 0, "extra": 0}

    def run(self, signals: Signals, time: TimeBase, rng: np.random.Generator) -> None:
        """Replace every stream of ``wire`` by its faulty copy; counts add up in ``counts``."""
        p = [self.scalar(k, 0.0, 1.0) for k in ("lost", "flipped", "extra")]
        out = []
        for stream in signals.need("wire", self.name):
            faulty, counts = inject_faults(stream, *p, rng)
            out.append(faulty)
            for k, v in counts.items():
                self.counts[k] += v
        signals["wire"] = out
