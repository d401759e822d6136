"""Occupancy-grid maps in the ROS map_server format (YAML + PGM/PNG).

The grid is stored the way nav_msgs/OccupancyGrid carries it: row 0 is the bottom of the map (smallest y),
values 0 (free) .. 100 (occupied) and -1 (unknown). Users can load maps made by SLAM toolboxes unchanged.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from PIL import Image, UnidentifiedImageError

from tb4.config import ConfigError, as_float, as_int, check_keys, load_yaml, require

__all__ = ["OccupancyMap", "load_map", "save_map", "FREE", "OCCUPIED", "UNKNOWN"]

FREE = 0
OCCUPIED = 100
UNKNOWN = -1

_MAP_KEYS = ("image", "resolution", "origin", "negate", "occupied_thresh", "free_thresh", "mode")


@dataclass
class OccupancyMap:
    """A 2D occupancy grid. `data[row, col]`, row 0 at `origin_y` (bottom), like nav_msgs/OccupancyGrid."""

    data: np.ndarray  # int8, shape (height, width)
    resolution: float
    origin_x: float = 0.0
    origin_y: float = 0.0
    origin_yaw: float = 0.0
    source: str | None = None

    def __post_init__(self) -> None:
        self.data = np.ascontiguousarray(self.data, dtype=np.int8)
        if self.data.ndim != 2 or self.data.size == 0:
            raise ValueError("map data must be a non-empty 2D array")
        if not (math.isfinite(self.resolution) and self.resolution > 0):
            raise ValueError(f"map resolution must be a positive number, got {self.resolution}")

    @property
    def height(self) -> int:
        return int(self.data.shape[0])

    @property
    def width(self) -> int:
        return int(self.data.shape[1])

    @property
    def size_x(self) -> float:
        return self.width * self.resolution

    @property
    def size_y(self) -> float:
        return self.height * self.resolution

    @property
    def bounds(self) -> tuple[float, float, float, float]:
        """(min_x, min_y, max_x, max_y) in the map frame (origin yaw is assumed 0 for bounds)."""
        return (self.origin_x, self.origin_y, self.origin_x + self.size_x, self.origin_y + self.size_y)

    def world_to_cell(self, x: float, y: float) -> tuple[int, int]:
        """(row, col) of the cell holding point (x, y); may be outside the grid."""
        return (
            int(math.floor((y - self.origin_y) / self.resolution)),
            int(math.floor((x - self.origin_x) / self.resolution)),
        )

    def cell_to_world(self, row: int, col: int) -> tuple[float, float]:
        """Centre of cell (row, col)."""
        return (
            self.origin_x + (col + 0.5) * self.resolution,
            self.origin_y + (row + 0.5) * self.resolution,
        )

    def in_bounds(self, x: float, y: float) -> bool:
        if not (math.isfinite(x) and math.isfinite(y)):
            return False
        row, col = self.world_to_cell(x, y)
        return 0 <= row < self.height and 0 <= col < self.width

    def value_at(self, x: float, y: float) -> int:
        """Occupancy at (x, y); points off the map read as UNKNOWN."""
        if not self.in_bounds(x, y):
            return UNKNOWN
        row, col = self.world_to_cell(x, y)
        return int(self.data[row, col])

    def occupied_mask(self) -> np.ndarray:
        """Cells a robot cannot enter: occupied (>= 65 in scale mode) or unknown."""
        return (self.data >= 65) | (self.data < 0)


def _parse_origin(value: Any, source: Path) -> tuple[float, float, float]:
    if not isinstance(value, (list, tuple)) or len(value) != 3:
        raise ConfigError(source, "origin", f"expected [x, y, yaw], got {value!r}")
    return (
        as_float(value[0], source, "origin[0]"),
        as_float(value[1], source, "origin[1]"),
        as_float(value[2], source, "origin[2]"),
    )


def load_map(yaml_path: str | Path) -> OccupancyMap:
    """Load a map_server map. Every problem is a ConfigError naming the file and the key."""
    yaml_path = Path(yaml_path)
    meta = load_yaml(yaml_path)
    check_keys(meta, _MAP_KEYS, yaml_path, required=("image", "resolution", "origin"))
    image_name = require(meta, "image", yaml_path)
    if not isinstance(image_name, str) or not image_name:
        raise ConfigError(yaml_path, "image", f"expected an image file name, got {image_name!r}")
    resolution = as_float(meta["resolution"], yaml_path, "resolution", minimum=1e-6)
    origin = _parse_origin(meta["origin"], yaml_path)
    negate = as_int(meta.get("negate", 0), yaml_path, "negate", minimum=0, maximum=1)
    occupied_thresh = as_float(meta.get("occupied_thresh", 0.65), yaml_path, "occupied_thresh", minimum=0, maximum=1)
    free_thresh = as_float(meta.get("free_thresh", 0.196), yaml_path, "free_thresh", minimum=0, maximum=1)
    if free_thresh >= occupied_thresh:
        raise ConfigError(yaml_path, "free_thresh", f"must be below occupied_thresh ({occupied_thresh})")
    mode = meta.get("mode", "trinary")
    if mode not in ("trinary", "scale", "raw"):
        raise ConfigError(yaml_path, "mode", f"expected trinary, scale or raw, got {mode!r}")

    image_path = Path(image_name) if Path(image_name).is_absolute() else yaml_path.parent / image_name
    try:
        with Image.open(image_path) as img:
            img.load()
            has_alpha = img.mode in ("LA", "RGBA", "PA")
            alpha = np.asarray(img.getchannel("A")) if has_alpha else None
            gray = np.asarray(img.convert("L"))
    except FileNotFoundError:
        raise ConfigError(yaml_path, "image", f"image file not found: {image_path}") from None
    except (UnidentifiedImageError, OSError, ValueError) as exc:
        raise ConfigError(yaml_path, "image", f"cannot read image {image_path}: {exc}") from None

    # every pixel value's occupancy, then a lookup per pixel: a warehouse map has 1.7 million pixels, and the
    # arithmetic done on each instead would more than double the load at every simulator's start
    data = _occupancy_of_levels(mode, negate, occupied_thresh, free_thresh)[gray]
    if mode == "scale" and alpha is not None:
        data[alpha < 255] = UNKNOWN
    return OccupancyMap(
        data=np.flipud(data),
        resolution=resolution,
        origin_x=origin[0],
        origin_y=origin[1],
        origin_yaw=origin[2],
        source=str(yaml_path),
    )


def _occupancy_of_levels(mode: str, negate: int, occupied_thresh: float, free_thresh: float) -> np.ndarray:
    """map_server's interpretation of each 8-bit pixel value 0..255 (same thresholds and rounding), as int8."""
    levels = np.arange(256, dtype=np.float64)
    if mode == "raw":
        raw = levels.astype(np.int16)
        raw[raw > 100] = UNKNOWN
        return raw.astype(np.int8)
    occ = levels / 255.0 if negate else (255.0 - levels) / 255.0
    out = np.full(levels.shape, UNKNOWN, dtype=np.int8)
    out[occ > occupied_thresh] = OCCUPIED
    out[occ < free_thresh] = FREE
    if mode == "scale":
        middle = (occ >= free_thresh) & (occ <= occupied_thresh)
        scaled = np.rint(99.0 * (occ - free_thresh) / (occupied_thresh - free_thresh)).astype(np.int8)
        out[middle] = scaled[middle]
    return out


def save_map(grid: OccupancyMap, yaml_path: str | Path) -> Path:
    """Write a trinary map_server map (PGM + YAML) next to each other; returns the YAML path."""
    yaml_path = Path(yaml_path)
    pgm_path = yaml_path.with_suffix(".pgm")
    pixels = np.full(grid.data.shape, 205, dtype=np.uint8)
    pixels[grid.data == FREE] = 254
    pixels[grid.data >= 65] = 0
    Image.fromarray(np.flipud(pixels), mode="L").save(pgm_path)
    yaml_path.write_text(
        f"image: {pgm_path.name}\n"
        f"mode: trinary\n"
        f"resolution: {grid.resolution}\n"
        f"origin: [{grid.origin_x}, {grid.origin_y}, {grid.origin_yaw}]\n"
        "negate: 0\n"
        "occupied_thresh: 0.65\n"
        "free_thresh: 0.196\n",  # not 0.25: 205 (unknown) must not read back as free (occ 0.196 < 0.25)
        encoding="utf-8",
    )
    return yaml_path
