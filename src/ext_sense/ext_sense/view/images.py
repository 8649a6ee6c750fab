"""RGB images as ``(height, width, 3)`` uint8 arrays, drawn with NumPy slicing only.

The live view renders 10-30 pictures a second beside the perception nodes on two cores, so no
plotting library is in the loop: a colour map lookup and filled rectangles are enough for taxel
grids, rasters and bars, and cost microseconds.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

Image = npt.NDArray[np.uint8]
"""``(height, width, 3)`` uint8, row-major, ``rgb8`` as Foxglove's RawImage names it."""

_ANCHORS = np.array(
    [  # viridis at 0, 0.25, 0.5, 0.75, 1: perceptually even, readable by colour-blind people
        (68, 1, 84),
        (59, 82, 139),
        (33, 145, 140),
        (94, 201, 98),
        (253, 231, 37),
    ],
    dtype=np.float64,
)
_LUT = np.stack(
    [
        np.interp(np.linspace(0, 1, 256), np.linspace(0, 1, len(_ANCHORS)), _ANCHORS[:, c])
        for c in range(3)
    ],
    axis=1,
).astype(np.uint8)

BACKGROUND = (24, 24, 24)
DEAD = (200, 30, 30)
SATURATED = (255, 255, 255)
ONSET = (255, 60, 60)
TRUTH = (60, 220, 90)
ESTIMATE = (255, 140, 0)
PROVISIONAL = (230, 200, 40)
FINAL = (90, 160, 255)
ROD = (150, 150, 150)


def colormap(x: npt.ArrayLike) -> Image:
    """Colours of values in [0, 1] (clipped; NaN is the background), shape ``x.shape + (3,)``."""
    v = np.asarray(x, dtype=np.float64)
    idx = np.clip(np.nan_to_num(v, nan=0.0) * 255.0 + 0.5, 0, 255).astype(np.intp)
    out = _LUT[idx]
    out[np.isnan(v)] = BACKGROUND
    return out


def blank(height: int, width: int, colour: tuple[int, int, int] = BACKGROUND) -> Image:
    """An image of one colour."""
    img = np.empty((height, width, 3), np.uint8)
    img[:] = colour
    return img


def fill(
    img: Image, top: int, left: int, height: int, width: int, colour: tuple[int, int, int]
) -> None:
    """Fill a rectangle, clipped to the image (in place)."""
    h, w = img.shape[:2]
    t, b = max(0, top), min(h, top + height)
    lft, r = max(0, left), min(w, left + width)
    if t < b and lft < r:
        img[t:b, lft:r] = colour


def frame(
    img: Image,
    top: int,
    left: int,
    height: int,
    width: int,
    colour: tuple[int, int, int],
    thickness: int = 2,
) -> None:
    """Draw a rectangle's outline, ``thickness`` pixels inside it (in place)."""
    k = thickness
    fill(img, top, left, k, width, colour)
    fill(img, top + height - k, left, k, width, colour)
    fill(img, top, left, height, k, colour)
    fill(img, top, left + width - k, height, k, colour)


def cross(img: Image, top: int, left: int, size: int, colour: tuple[int, int, int]) -> None:
    """Draw an X over a ``size`` x ``size`` cell (in place): a dead taxel."""
    i = np.arange(size)
    for d in (-1, 0, 1):
        j = np.clip(i + d, 0, size - 1)
        for rows, cols in ((top + i, left + j), (top + i, left + size - 1 - j)):
            ok = (rows >= 0) & (rows < img.shape[0]) & (cols >= 0) & (cols < img.shape[1])
            img[rows[ok], cols[ok]] = colour
