"""Serial byte source through pyserial: device paths, ptys and pyserial URLs such as ``loop://``."""

from __future__ import annotations

import contextlib
import time
from collections.abc import Callable

from ext_sense_drivers.transports.base import Chunk
from ext_sense_drivers.transports.errors import TransportError

_MAX_READ = 65536


class SerialTransport:
    """Reads what the port (a device, pty or pyserial URL) has, waiting at most the timeout.

    ``clock`` stamps each read (monotonic ns).
    """

    def __init__(
        self, port: str, baud: int = 115200, clock: Callable[[], int] = time.monotonic_ns
    ) -> None:
        if not port:
            raise TransportError("The 'port' parameter must name a serial device. Got '' instead.")
        if int(baud) <= 0:
            raise TransportError(f"The 'baud' parameter must be > 0. Got {baud} instead.")
        self.port = port
        self.baud = int(baud)
        self._clock = clock
        self._serial = None
        self._timeout_s = 0.0

    @property
    def description(self) -> str:
        """The port name."""
        return self.port

    @property
    def exhausted(self) -> bool:
        """A serial port never ends."""
        return False

    @property
    def is_open(self) -> bool:
        """Whether the port is open."""
        return self._serial is not None

    def open(self) -> None:
        """Open the port (exclusive access where the OS supports it)."""
        import serial

        self.close()
        try:
            extra = {} if "://" in self.port else {"exclusive": True}
            self._serial = serial.serial_for_url(
                self.port, baudrate=self.baud, timeout=0.0, **extra
            )
            self._timeout_s = 0.0
        except (serial.SerialException, OSError, ValueError) as err:
            raise TransportError(f"cannot open serial port {self.port!r}: {err}") from err

    def read(self, timeout_s: float) -> Chunk:
        """Bytes that arrived within ``timeout_s`` (all that are waiting, up to 64 KiB)."""
        import serial

        if self._serial is None:
            raise TransportError(f"serial port {self.port!r} is not open")
        try:
            timeout_s = max(0.0, float(timeout_s))
            if timeout_s != self._timeout_s:  # setting it reconfigures the port: only on change
                self._serial.timeout = self._timeout_s = timeout_s
            first = self._serial.read(1)
            if not first:
                return Chunk(b"", self._clock())
            waiting = self._serial.in_waiting
            rest = self._serial.read(min(waiting, _MAX_READ)) if waiting else b""
        except (serial.SerialException, OSError, TypeError) as err:
            # pyserial raises TypeError from in_waiting on a port closed underneath it.
            raise TransportError(f"serial port {self.port!r} vanished: {err}") from err
        return Chunk(bytes(first + rest), self._clock())

    def write(self, data: bytes) -> int:
        """Write bytes (for devices that take commands, and for ``loop://`` tests)."""
        import serial

        if self._serial is None:
            raise TransportError(f"serial port {self.port!r} is not open")
        try:
            return int(self._serial.write(data) or 0)
        except (serial.SerialException, OSError) as err:
            raise TransportError(f"serial port {self.port!r} vanished: {err}") from err

    def close(self) -> None:
        """Close the port; errors while closing a vanished port are ignored."""
        ser, self._serial = self._serial, None
        if ser is not None:
            with contextlib.suppress(Exception):  # the device is gone already
                ser.close()
