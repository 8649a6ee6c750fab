"""CAN byte source and sink (python-can): a stream in consecutive frames under one id."""

from __future__ import annotations

import contextlib
import time
from collections.abc import Callable

from ext_sense_drivers.transports.base import Chunk
from ext_sense_drivers.transports.errors import TransportError

CAN_PAYLOAD = 8
"""Bytes per classic CAN data frame."""

_MAX_FRAMES_PER_READ = 4096


def split_frames(data: bytes, size: int = CAN_PAYLOAD) -> list[bytes]:
    """Cut a byte stream into consecutive frame payloads of at most ``size`` (1..8) bytes."""
    if not 1 <= size <= CAN_PAYLOAD:
        raise TransportError(f"The 'size' parameter must be in 1..8. Got {size} instead.")
    return [bytes(data[i : i + size]) for i in range(0, len(data), size)]


def _check_id(arbitration_id: int, extended: bool) -> int:
    limit = 0x1FFFFFFF if extended else 0x7FF
    if not 0 <= int(arbitration_id) <= limit:
        raise TransportError(
            f"The 'arbitration_id' parameter must be in 0..{limit:#x} "
            f"({'extended' if extended else 'standard'} id). Got {arbitration_id:#x} instead."
        )
    return int(arbitration_id)


def _open_bus(interface: str, channel: str, bitrate: int | None):  # -> can.BusABC
    import can

    kwargs = {"interface": interface, "channel": channel}
    if bitrate:
        kwargs["bitrate"] = int(bitrate)
    try:
        return can.Bus(**kwargs)
    except (can.CanError, OSError, ValueError, ImportError, NotImplementedError) as err:
        raise TransportError(f"cannot open CAN bus {interface}:{channel}: {err}") from err


class CanTransport:
    """Reads the stream's frames from a python-can bus and joins their payloads.

    Only frames under ``arbitration_id`` (29-bit when ``extended``) count; others and error
    frames are counted and ignored. ``clock`` stamps each read (monotonic ns).
    """

    def __init__(
        self,
        interface: str,
        channel: str,
        arbitration_id: int,
        *,
        extended: bool = False,
        bitrate: int | None = None,
        clock: Callable[[], int] = time.monotonic_ns,
    ) -> None:
        self.interface = interface
        self.channel = channel
        self.arbitration_id = _check_id(arbitration_id, extended)
        self.extended = bool(extended)
        self.bitrate = bitrate
        self._clock = clock
        self._bus = None
        self.foreign_frames = 0
        """Frames seen with another arbitration id (ignored)."""
        self.error_frames = 0
        """Error frames and remote frames seen under the stream's id (ignored)."""

    @property
    def description(self) -> str:
        """``interface:channel#id``."""
        return f"{self.interface}:{self.channel}#{self.arbitration_id:#x}"

    @property
    def exhausted(self) -> bool:
        """A bus never ends."""
        return False

    def open(self) -> None:
        """Connect to the bus."""
        self.close()
        self._bus = _open_bus(self.interface, self.channel, self.bitrate)

    def read(self, timeout_s: float) -> Chunk:
        """Payload bytes of the stream's frames that arrived within ``timeout_s``, in order."""
        import can

        if self._bus is None:
            raise TransportError(f"CAN bus {self.description} is not open")
        parts: list[bytes] = []
        try:
            msg = self._bus.recv(timeout=max(0.0, float(timeout_s)))
            n = 0
            while msg is not None and n < _MAX_FRAMES_PER_READ:
                self._take(msg, parts)
                n += 1
                msg = self._bus.recv(timeout=0.0)
            if msg is not None:
                self._take(msg, parts)
        except (can.CanError, OSError, AttributeError) as err:
            # AttributeError: some interfaces fail that way on a bus shut down underneath them.
            raise TransportError(f"CAN bus {self.description} vanished: {err}") from err
        return Chunk(b"".join(parts), self._clock())

    def _take(self, msg: object, parts: list[bytes]) -> None:
        if msg.arbitration_id != self.arbitration_id or msg.is_extended_id != self.extended:
            self.foreign_frames += 1
        elif msg.is_error_frame or msg.is_remote_frame:
            self.error_frames += 1
        else:
            parts.append(bytes(msg.data[: msg.dlc]))

    def close(self) -> None:
        """Shut the bus connection down."""
        bus, self._bus = self._bus, None
        if bus is not None:
            with contextlib.suppress(Exception):  # the bus is gone already
                bus.shutdown()


class CanSink:
    """Writes a byte stream onto a CAN bus as consecutive frames (arguments as CanTransport)."""

    def __init__(
        self,
        interface: str,
        channel: str,
        arbitration_id: int,
        *,
        extended: bool = False,
        bitrate: int | None = None,
    ) -> None:
        self.interface = interface
        self.channel = channel
        self.arbitration_id = _check_id(arbitration_id, extended)
        self.extended = bool(extended)
        self._bus = _open_bus(interface, channel, bitrate)
        self.frames_sent = 0

    def write(self, data: bytes, timeout_s: float | None = 0.1) -> int:
        """Send ``data`` as frames; return the bytes sent (TransportError if refused)."""
        import can

        sent = 0
        for payload in split_frames(data):
            msg = can.Message(
                arbitration_id=self.arbitration_id, data=payload, is_extended_id=self.extended
            )
            try:
                self._bus.send(msg, timeout=timeout_s)
            except (can.CanError, OSError) as err:
                raise TransportError(
                    f"CAN bus {self.interface}:{self.channel} refused a frame after {sent} "
                    f"bytes: {err}"
                ) from err
            sent += len(payload)
            self.frames_sent += 1
        return sent

    def close(self) -> None:
        """Shut the bus connection down."""
        with contextlib.suppress(Exception):  # the bus is gone already
            self._bus.shutdown()

    def __enter__(self) -> CanSink:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
