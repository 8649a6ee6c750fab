"""Robotiq link and behaviour decision figures, measured side by side in one run.

Usage: python bench/bench_behaviours.py [--quick]

- CRC-16/Modbus: table-driven ``crc16_modbus`` vs the bitwise definition, per status reply.
- One status poll through the real client, in memory vs over the pty (``PtyGripper``): p50 /
  p99 and polls/s (a real 2F at 115200 baud adds 1.3 ms of wire time per poll). Target: a
  10 Hz poll uses well under 10% of the link's time.
- Food contact decision: time per arm state through ``FoodMachine.on_arm_state`` (the Panda
  state arrives at about 30 Hz, so the decision budget is 33 ms).
"""

from __future__ import annotations

import argparse
import statistics
import time

from ext_sense_behaviours.food import FoodConfig, FoodMachine
from ext_sense_behaviours.records import ArmState
from ext_sense_drivers.robotiq import RobotiqClient, crc16_modbus, modbus
from ext_sense_sim.devices.robotiq_emulator import GripperModel, PtyGripper, RobotiqEmulator


def crc_bitwise(data: bytes) -> int:
    crc = 0xFFFF
    for byte in data:
        crc ^= byte
        for _ in range(8):
            crc = (crc >> 1) ^ 0xA001 if crc & 1 else crc >> 1
    return crc


def time_per_call(fn, n: int) -> float:
    t0 = time.perf_counter()
    for _ in range(n):
        fn()
    return (time.perf_counter() - t0) / n


class Loopback:
    def __init__(self, emulator: RobotiqEmulator) -> None:
        self.emulator, self.timeout, self._rx = emulator, 0.5, b""

    def write(self, data: bytes) -> int:
        self._rx += self.emulator.handle(bytes(data)) or b""
        return len(data)

    def read(self, size: int = 1) -> bytes:
        out, self._rx = self._rx[:size], self._rx[size:]
        return out

    def reset_input_buffer(self) -> None:
        self._rx = b""

    def close(self) -> None:
        pass


def poll_latencies(client: RobotiqClient, n: int) -> list[float]:
    out = []
    for _ in range(n):
        t0 = time.perf_counter()
        client.read_status()
        out.append(time.perf_counter() - t0)
    return out


def p(values: list[float], q: float) -> float:
    return sorted(values)[min(len(values) - 1, int(q * len(values)))]


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="small run (a few seconds)")
    args = parser.parse_args()
    n_crc = 2_000 if args.quick else 50_000
    n_poll = 100 if args.quick else 2_000
    n_food = 2_000 if args.quick else 100_000

    reply = modbus.encode_read_reply(9, 3, [0xB900, 0x00FF, 0xBD00])[:-2]
    t_table = time_per_call(lambda: crc16_modbus(reply), n_crc)
    t_bit = time_per_call(lambda: crc_bitwise(reply), n_crc)
    print(
        f"CRC of a 9-byte status reply: table {t_table * 1e6:.2f} us, bitwise "
        f"{t_bit * 1e6:.2f} us, ratio {t_bit / t_table:.1f}x"
    )

    mem = RobotiqClient(Loopback(RobotiqEmulator(GripperModel(activation_s=0.0))))
    mem.activate(poll_s=0.0)
    lat_mem = poll_latencies(mem, n_poll)
    with PtyGripper(RobotiqEmulator(GripperModel(activation_s=0.0))) as pty:
        client = RobotiqClient.open(pty.path, timeout_s=0.5)
        try:
            client.activate(poll_s=0.0)
            lat_pty = poll_latencies(client, n_poll)
        finally:
            client.close()
    for name, lat in (("in-memory", lat_mem), ("pty", lat_pty)):
        print(
            f"status poll, {name:9s}: p50 {p(lat, 0.5) * 1e3:.3f} ms, p99 "
            f"{p(lat, 0.99) * 1e3:.3f} ms, {1 / statistics.fmean(lat):.0f} polls/s"
        )
    print(
        f"pty / in-memory p50 ratio: {p(lat_pty, 0.5) / p(lat_mem, 0.5):.1f}x; "
        f"10 Hz polling occupies {10 * p(lat_pty, 0.5) * 100:.2f}% of the pty link's time"
    )

    machine = FoodMachine(
        FoodConfig(contact_threshold_n=1e9, stop_height_m=-1.0, max_lowering_ns=10**18)
    )
    machine.start(ArmState(0, 0.16, (0.0, 0.0, 0.0)))
    states = [ArmState(i, 0.16, (0.1, 0.2, 3.0)) for i in range(1, n_food + 1)]
    t0 = time.perf_counter()
    for s in states:
        machine.on_arm_state(s)
    t_food = (time.perf_counter() - t0) / n_food
    print(
        f"food contact decision: {t_food * 1e6:.2f} us per arm state; budget at 30 Hz is "
        f"33 ms ({33e-3 / t_food:.0f}x headroom)"
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
