"""A contact window as a raster: one row per channel (taxel), time left to right, onset marked.

Columns are summed down to at most ``max_columns`` and rows stretched, so a 1400-sample window
fits a panel and one PAC channel is a visible band.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from ext_sense.view.errors import ViewError
from ext_sense.view.images import FINAL, ONSET, PROVISIONAL, Image, colormap, fill


def raster_image(
    data: npt.ArrayLike,
    pre_onset_ns: int,
    sample_period_ns: int,
    *,
    provisional: bool = False,
    max_columns: int = 400,
    min_height: int = 160,
    finger_rows: int = 40,
) -> Image:
    """Draw one ``(n_channels, n_samples)`` window as an RGB image, the onset column red.

    ``pre_onset_ns`` is the signal before the onset (negative: the window starts after it);
    a provisional window gets a yellow band on top (final: blue); samples are summed into at
    most ``max_columns`` columns, rows repeated to ``min_height`` pixels; a grey line parts
    every ``finger_rows`` channels (0: none).

    Raises:
        ViewError: ``data`` is not 2-D with at least one sample, or the period is not positive.
    """
    d = np.asarray(data, dtype=np.float64)
    if d.ndim != 2 or d.shape[0] < 1 or d.shape[1] < 1:
        raise ViewError(
            f"The 'data' parameter must be (n_channels, n_samples). Got {d.shape} instead."
        )
    if sample_period_ns <= 0:
        raise ViewError(
            f"The 'sample_period_ns' parameter must be > 0. Got {sample_period_ns} instead."
        )
    n_ch, n = d.shape
    group = max(1, -(-n // max_columns))
    cols = -(-n // group)
    padded = np.zeros((n_ch, cols * group))
    padded[:, :n] = np.abs(d) if d.min() < 0 else d
    binned = padded.reshape(n_ch, cols, group).sum(axis=2)
    scale = np.percentile(binned[binned > 0], 99) if np.any(binned > 0) else 1.0
    img = colormap(np.log1p(binned) / np.log1p(max(scale, 1e-9)))
    reps = max(1, -(-min_height // n_ch))
    img = np.repeat(img, reps, axis=0)
    width = max(1, -(-max_columns // cols)) if cols < max_columns // 2 else 1
    img = np.ascontiguousarray(np.repeat(img, width, axis=1))
    if finger_rows and n_ch > finger_rows:
        for r in range(finger_rows, n_ch, finger_rows):
            fill(img, r * reps - 1, 0, 2, img.shape[1], (128, 128, 128))
    onset_col = round(pre_onset_ns / sample_period_ns / group * width)
    if 0 <= onset_col < img.shape[1]:
        fill(img, 0, onset_col - 1, img.shape[0], 3, ONSET)
    band = np.empty((6, img.shape[1], 3), np.uint8)
    band[:] = PROVISIONAL if provisional else FINAL
    return np.ascontiguousarray(np.concatenate([band, img], axis=0))
