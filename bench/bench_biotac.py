"""BioTac bridge decoding throughput: vectorised BridgeDecoder vs the per-byte reference.

Usage: python bench/bench_biotac.py [--quick]

Target: 50,000 frames/s on one core = 100 x (5 sensors x 100 frames/s), in CPU time of this
process (so "on one core" on a shared machine). Both decoders read the same stream (5 sensors
round robin, 1% of frames with a bit flip) in the same chunks; their counters must be equal.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from ext_sense_drivers.biotac.decoder import BridgeDecoder
from ext_sense_drivers.biotac.encoder import encode_frames
from ext_sense_drivers.biotac.reference import ReferenceDecoder
from ext_sense_drivers.biotac.words import encode_values

TARGET_FPS = 100 * 5 * 100


def make_stream(n_frames: int, seed: int = 0) -> bytes:
    rng = np.random.default_rng(seed)
    values = rng.integers(0, 4096, (n_frames, 44))
    sensor = np.arange(n_frames) % 5
    seq = (np.arange(n_frames) // 5) % 65536
    data = bytearray(encode_frames(seq, sensor, encode_values(values)))
    for k in rng.choice(n_frames, n_frames // 100, replace=False):
        data[k * 96 + int(rng.integers(6, 94))] ^= 1 << int(rng.integers(0, 8))
    return bytes(data)


def run(decoder, stream: bytes, chunk: int) -> tuple[float, int]:
    t0 = time.process_time()
    n = 0
    for i in range(0, len(stream), chunk):
        out = decoder.feed(stream[i : i + chunk])
        n += out.n if hasattr(out, "n") else len(out)
    out = decoder.flush()
    n += out.n if hasattr(out, "n") else len(out)
    return time.process_time() - t0, n


def node_cost(stream: bytes, n_frames: int) -> float:
    """CPU seconds per frame of the node's path: decode one frame per call, stamp, publish."""
    import tempfile

    import rclpy
    from rclpy.context import Context
    from rclpy.parameter import Parameter

    from ext_sense_drivers.nodes.biotac_driver import BioTacDriverNode

    ctx = Context()
    rclpy.init(context=ctx)
    with tempfile.NamedTemporaryFile(suffix=".bin") as empty:
        node = BioTacDriverNode(
            context=ctx,
            parameter_overrides=[
                Parameter("transport", value="file"),
                Parameter("file_path", value=empty.name),
            ],
        )
        try:
            node.reader.stop()
            t0 = time.process_time()
            for i in range(0, n_frames * 96, 96):
                frames = node.decoder.feed(stream[i : i + 96])
                node._publish(frames, np.full(frames.n, time.monotonic_ns(), dtype=np.int64))
            dt = time.process_time() - t0
        finally:
            node.destroy_node()
            rclpy.try_shutdown(context=ctx)
    return dt / n_frames


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="small run (a few seconds)")
    args = parser.parse_args()
    n_fast = 20_000 if args.quick else 200_000
    n_ref = 2_000 if args.quick else 10_000
    fast_stream = make_stream(n_fast)
    ref_stream = fast_stream[: n_ref * 96]

    print(f"BioTac bridge decode, frames/s (target {TARGET_FPS:,} = 100 x 5 sensors x 100 Hz)")
    head = ("chunk bytes", "vectorised", "per-byte ref", "ratio", "vs target")
    print("{:>12} {:>12} {:>13} {:>7} {:>10}".format(*head))
    for chunk in (96, 960, 4096, 65536):
        n = n_fast if chunk >= 960 else n_fast // 10
        dt_fast, got_fast = run(BridgeDecoder(), fast_stream[: n * 96], chunk)
        dt_ref, got_ref = run(ReferenceDecoder(), ref_stream, chunk)
        fps_fast, fps_ref = got_fast / dt_fast, got_ref / dt_ref
        print(
            f"{chunk:>12} {fps_fast:>12,.0f} {fps_ref:>13,.0f} {fps_fast / fps_ref:>6.1f}x "
            f"{fps_fast / TARGET_FPS:>9.2f}x"
        )

    fast, ref = BridgeDecoder(), ReferenceDecoder()
    run(fast, ref_stream, 4096)
    run(ref, ref_stream, 4096)
    per_frame = node_cost(fast_stream, 1000 if args.quick else 5000)
    print(
        f"node path (decode 1 frame/call + clock + BioTacFrame publish): {per_frame * 1e6:.0f} us "
        f"CPU per frame = {per_frame * 500 * 100:.1f}% of a core at 5 sensors x 100 Hz"
    )
    same = fast.counters == ref.counters
    print(f"same counters on {n_ref} frames: {same}; {fast.counters.summary()}")
    return 0 if same else 1


if __name__ == "__main__":
    raise SystemExit(main())
