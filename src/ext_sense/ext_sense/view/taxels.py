"""The taxel grid: what each taxel feels now, in its real place, with broken ones marked.

NUSkin: each finger's 8 x 5 lattice coloured by event rate on a log scale; a taxel silent while
its finger fires is crossed out (dead), one at the top rate framed (saturated). BioTac: the 19
electrodes on a 4 x 5 grid by distance from rest, crossed out at 0, framed at the 12-bit top.
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt

from ext_sense.view.errors import ViewError
from ext_sense.view.images import DEAD, SATURATED, Image, blank, colormap, cross, frame
from ext_sense_drivers.nuskin.layout import COLUMNS, N_TAXELS, ROWS, TAXELS_PER_FINGER

N_FINGERS = N_TAXELS // TAXELS_PER_FINGER
N_ELECTRODES = 19
ELECTRODE_ROWS, ELECTRODE_COLUMNS = 4, 5
ELECTRODE_TOP = 4095
"""The BioTac's 12-bit electrode reading at saturation."""


class TaxelActivity:
    """Recent event rate of each NUSkin taxel, smoothed over ``tau_s``.

    :meth:`add` counts each batch; :meth:`update`, at display rate, turns counts into rates. A
    taxel silent ``dead_after_s`` while its finger fires is dead; one at ``saturation_hz``
    (events/s) or above is saturated.
    """

    def __init__(
        self, tau_s: float = 0.5, dead_after_s: float = 10.0, saturation_hz: float = 3800.0
    ) -> None:
        if not tau_s > 0:
            raise ViewError(f"The 'tau_s' parameter must be > 0. Got {tau_s} instead.")
        self.tau_s = tau_s
        self.dead_after_ns = int(dead_after_s * 1e9)
        self.saturation_hz = saturation_hz
        self.counts = np.zeros(N_TAXELS, np.int64)
        self.rate_hz = np.zeros(N_TAXELS, np.float64)
        self.last_seen_ns = np.full(N_TAXELS, -1, np.int64)
        self.rejected = 0
        """Events whose taxel id is not in 1..80: counted, not drawn."""
        self._start_ns: int | None = None
        self._last_ns: int | None = None

    def add(self, taxel: npt.ArrayLike) -> None:
        """Count one batch of events by taxel id (1..80)."""
        ids = np.asarray(taxel, dtype=np.int64)
        ok = (ids >= 1) & (ids <= N_TAXELS)
        self.rejected += int(ids.size - np.count_nonzero(ok))
        self.counts += np.bincount(ids[ok] - 1, minlength=N_TAXELS)

    def update(self, now_ns: int) -> npt.NDArray[np.float64]:
        """Fold the counts since the last update into the rates; returns them, events/s."""
        if self._last_ns is None:
            self._start_ns = self._last_ns = now_ns
        dt = (now_ns - self._last_ns) / 1e9
        self.last_seen_ns[self.counts > 0] = now_ns
        if dt > 0:
            keep = math.exp(-dt / self.tau_s)
            self.rate_hz = keep * self.rate_hz + (1.0 - keep) * (self.counts / dt)
            self.counts[:] = 0
            self._last_ns = now_ns
        return self.rate_hz

    def finger_rates(self) -> npt.NDArray[np.float64]:
        """Summed rate of each finger (left, right), events/s."""
        return self.rate_hz.reshape(N_FINGERS, TAXELS_PER_FINGER).sum(axis=1)

    def dead(self, now_ns: int) -> npt.NDArray[np.bool_]:
        """Taxels silent for ``dead_after_s`` while another taxel of their finger was not."""
        if self._start_ns is None or now_ns - self._start_ns < self.dead_after_ns:
            return np.zeros(N_TAXELS, bool)
        recent = (self.last_seen_ns >= 0) & (now_ns - self.last_seen_ns <= self.dead_after_ns)
        finger_active = recent.reshape(N_FINGERS, -1).any(axis=1)
        return ~recent & np.repeat(finger_active, TAXELS_PER_FINGER)

    def saturated(self) -> npt.NDArray[np.bool_]:
        """Taxels firing at the sensor's top rate."""
        return self.rate_hz >= self.saturation_hz


def nuskin_grid(
    rate_hz: npt.ArrayLike,
    dead: npt.ArrayLike,
    saturated: npt.ArrayLike,
    *,
    top_hz: float = 4000.0,
    cell: int = 24,
) -> Image:
    """Both fingers' 8 x 5 lattices, left finger on the left, ``cell`` pixels a taxel.

    ``rate_hz``, ``dead`` and ``saturated`` are of taxels 1..80, shape ``(80,)`` (else
    ViewError); dead ones are crossed out, saturated ones framed; ``top_hz`` tops the log scale.
    """
    rate, dead_, sat = (np.asarray(a) for a in (rate_hz, dead, saturated))
    if any(a.shape != (N_TAXELS,) for a in (rate, dead_, sat)):
        raise ViewError(
            f"The 'rate_hz', 'dead' and 'saturated' parameters must have shape (80,). Got "
            f"{rate.shape}, {dead_.shape}, {sat.shape} instead."
        )
    level = np.log1p(np.maximum(rate, 0.0)) / math.log1p(top_hz)
    margin, gap = cell // 3, cell
    img = blank(ROWS * cell + 2 * margin, N_FINGERS * COLUMNS * cell + gap + 2 * margin)
    colours = colormap(level)
    for k in range(N_TAXELS):
        finger, idx = divmod(k, TAXELS_PER_FINGER)
        row, col = divmod(idx, COLUMNS)
        top = margin + row * cell
        left = margin + finger * (COLUMNS * cell + gap) + col * cell
        img[top + 1 : top + cell - 1, left + 1 : left + cell - 1] = colours[k]
        if dead_[k]:
            cross(img, top + 2, left + 2, cell - 4, DEAD)
        elif sat[k]:
            frame(img, top, left, cell, cell, SATURATED, thickness=3)
    return img


class ElectrodeActivity:
    """The latest BioTac electrode values of each sensor and their resting values.

    The resting value is the mean of a sensor's first ``baseline_frames`` frames.
    """

    def __init__(self, baseline_frames: int = 20) -> None:
        self.baseline_frames = baseline_frames
        self.latest: dict[int, npt.NDArray[np.float64]] = {}
        self._sums: dict[int, npt.NDArray[np.float64]] = {}
        self._n: dict[int, int] = {}

    def add(self, sensor_id: int, electrodes: npt.ArrayLike) -> None:
        """Take one frame's 19 electrode values (ViewError: not 19)."""
        e = np.asarray(electrodes, dtype=np.float64)
        if e.shape != (N_ELECTRODES,):
            raise ViewError(
                f"The 'electrodes' parameter must have shape (19,). Got {e.shape} instead."
            )
        self.latest[sensor_id] = e
        n = self._n.get(sensor_id, 0)
        if n < self.baseline_frames:
            self._sums[sensor_id] = self._sums.get(sensor_id, np.zeros(N_ELECTRODES)) + e
            self._n[sensor_id] = n + 1

    def baseline(self, sensor_id: int) -> npt.NDArray[np.float64]:
        """The resting values of one sensor (its first frames' mean)."""
        return self._sums[sensor_id] / self._n[sensor_id]

    def sensors(self) -> list[int]:
        """Sensor ids seen, sorted."""
        return sorted(self.latest)


def biotac_grid(activity: ElectrodeActivity, *, span: float = 400.0, cell: int = 24) -> Image:
    """Each sensor's 19 electrodes on a 4 x 5 grid in index order, sensors side by side.

    Colour: ``|value - resting| / span`` clipped to 1. An electrode reading 0 is crossed out,
    one at the 12-bit top framed white. No sensor seen yet: an empty grid for one sensor.
    """
    sensors = activity.sensors() or [0]
    margin, gap = cell // 3, cell
    width = len(sensors) * ELECTRODE_COLUMNS * cell + (len(sensors) - 1) * gap + 2 * margin
    img = blank(ELECTRODE_ROWS * cell + 2 * margin, width)
    for s, sid in enumerate(sensors):
        values = activity.latest.get(sid)
        if values is None:
            continue
        colours = colormap(np.abs(values - activity.baseline(sid)) / span)
        for k in range(N_ELECTRODES):
            row, col = divmod(k, ELECTRODE_COLUMNS)
            top = margin + row * cell
            left = margin + s * (ELECTRODE_COLUMNS * cell + gap) + col * cell
            img[top + 1 : top + cell - 1, left + 1 : left + cell - 1] = colours[k]
            if values[k] <= 0:
                cross(img, top + 2, left + 2, cell - 4, DEAD)
            elif values[k] >= ELECTRODE_TOP:
                frame(img, top, left, cell, cell, SATURATED, thickness=3)
    return img
