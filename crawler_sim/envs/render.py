"""The crawler drawn into an RGB array with numpy only (no matplotlib: cheap enough per step).

The camera follows the centre of mass; ground marks every ``MARK`` metres move under the
crawler, so forward motion reads as marks sliding left. Each body is a box whose colour says
its contact state: grey stuck, red sliding forward, blue sliding backward; a dark bar joins
neighbours (the linkage).
"""
from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

__all__ = ['draw', 'COLOURS']

#: contact state (+1 forward, 0 stuck, -1 backward) -> RGB
COLOURS = {1: (220, 60, 50), 0: (120, 120, 120), -1: (50, 90, 220)}
MARK = 0.05          # m between ground marks
_SKY, _GROUND, _LINK = (245, 245, 240), (190, 170, 130), (40, 40, 40)


def draw(x: NDArray[np.float64], contact: NDArray, masses: NDArray[np.float64],
         span: float, height: int = 120, width: int = 480) -> NDArray[np.uint8]:
    """An (height, width, 3) uint8 image of bodies at ``x`` [m] (shape (p,)), coloured by
    ``contact``, box sizes growing with the cube root of ``masses``; ``span`` [m] is the
    width shown (centred on the mass-weighted mean of x)."""
    img = np.empty((height, width, 3), dtype=np.uint8)
    img[:] = _SKY
    ground = int(height * 0.75)
    img[ground:] = _GROUND
    centre = float(masses @ x) / float(masses.sum())
    scale = width / span                                    # px per m
    # ground marks at multiples of MARK in view
    first = np.ceil((centre - span / 2) / MARK)
    for k in np.arange(first, first + span / MARK + 1):
        px = int(round((k * MARK - centre) * scale + width / 2))
        if 0 <= px < width:
            img[ground:ground + height // 10, px] = _LINK
    size = np.cbrt(masses / masses.max())
    half = np.maximum(2, (size * height * 0.12)).astype(int)
    cols = np.clip(np.round((x - centre) * scale + width / 2).astype(int), 0, width - 1)
    mid = ground - int(height * 0.12)
    for i in range(len(x) - 1):                             # linkages
        a, b = sorted((cols[i], cols[i + 1]))
        img[mid - 1:mid + 2, a:b + 1] = _LINK
    for i in range(len(x)):
        h = half[i]
        img[max(0, ground - 2 * h):ground, max(0, cols[i] - h):cols[i] + h + 1] = \
            COLOURS.get(int(contact[i]), COLOURS[0])
    return img
