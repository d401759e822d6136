"""Grids as the page draws them: indexed PNG images (one byte per cell, a palette with alpha), encoded by Pillow.

An indexed image keeps a 1000 x 1000 map to a few kilobytes and leaves the colours to one palette per layer.
"""

from __future__ import annotations

import io
from dataclasses import dataclass

import numpy as np
from PIL import Image

__all__ = ["Grid", "MAP_PALETTE", "COSTMAP_PALETTE", "encode_indexed_png", "grid_png"]


@dataclass(frozen=True)
class Grid:
    """An OccupancyGrid as plain values: `data[row, col]` int8 with row 0 at origin_y (bottom)."""

    data: np.ndarray
    resolution: float
    origin_x: float
    origin_y: float
    frame: str = "map"
    origin_yaw: float = 0.0

    @property
    def width(self) -> int:
        return int(self.data.shape[1])

    @property
    def height(self) -> int:
        return int(self.data.shape[0])

    def signature(self) -> tuple[int, int, float, float, float]:
        return (self.width, self.height, round(self.resolution, 6), round(self.origin_x, 4), round(self.origin_y, 4))


def _palette_map() -> np.ndarray:
    """OccupancyGrid values (0..100, -1 as 255) to RGBA: free white, occupied near-black, unknown grey."""
    pal = np.zeros((256, 4), dtype=np.uint8)
    shade = (250 - np.arange(101) * 2.25).astype(np.uint8)  # 0 -> 250 (free) ... 100 -> 25 (wall)
    pal[:101, :3] = shade[:, None]
    pal[:101, 3] = 255
    pal[101:255] = (120, 120, 140, 255)  # out-of-range values: visible, never confused with free space
    pal[255] = (176, 184, 194, 255)  # unknown (-1)
    return pal


def _palette_costmap() -> np.ndarray:
    """Costmap values (0..100 scaled from Nav2's 0..254) to translucent RGBA, close to RViz's 'costmap' scheme."""
    pal = np.zeros((256, 4), dtype=np.uint8)
    for v in range(1, 99):  # inflation: blue (low cost) through green/yellow to red (high cost)
        t = v / 98.0
        pal[v] = (int(255 * min(1.0, 2 * t)), int(255 * min(1.0, 2 - 2 * t) * 0.85), int(255 * (1 - t) ** 2), 110)
    pal[99] = (0, 190, 225, 150)  # inscribed: cyan
    pal[100] = (170, 40, 200, 150)  # lethal: purple
    pal[255] = (0, 0, 0, 0)  # unknown: transparent
    return pal


MAP_PALETTE = _palette_map()
COSTMAP_PALETTE = _palette_costmap()


def encode_indexed_png(pixels: np.ndarray, palette: np.ndarray) -> bytes:
    """An 8-bit indexed PNG (PLTE + tRNS) of `pixels` (uint8, row 0 at the top) with an RGBA `palette`."""
    pixels = np.ascontiguousarray(pixels, dtype=np.uint8)
    if pixels.ndim != 2 or pixels.size == 0:
        raise ValueError("pixels must be a non-empty 2D array")
    height, width = pixels.shape
    image = Image.frombytes("P", (width, height), pixels.tobytes())
    image.putpalette(np.asarray(palette, dtype=np.uint8).reshape(256, 4).tobytes(), rawmode="RGBA")
    out = io.BytesIO()
    image.save(out, format="PNG", compress_level=6)
    return out.getvalue()


def grid_png(grid: Grid, palette: np.ndarray) -> bytes:
    """PNG of a grid as the page draws it: top row = highest y, so flip the bottom-up grid."""
    pixels = np.asarray(grid.data, dtype=np.int8).view(np.uint8)[::-1]
    return encode_indexed_png(pixels, palette)
