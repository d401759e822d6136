#!/usr/bin/env python3
"""Draw the maps of our shipped worlds (warehouse, depot, maze) and write them as map_server PGM + YAML.

The maps are our own design, drawn from simple shapes with NumPy so they can be regenerated bit for bit:
``python tools/draw_worlds.py`` rewrites ``src/tb4/worlds/<name>_map.{pgm,yaml}``; ``--check`` only compares
the freshly drawn maps with the committed files and exits 1 if they differ. Extents and resolutions follow the
upstream TurtleBot 4 maps, so coordinates from the tutorials land in sensible places. In every world the robot
docks at (0, 0) facing +x, with the dock station body just ahead of it (x 0.19..0.39 m).
"""

from __future__ import annotations

import argparse
import math
import sys
from collections.abc import Callable
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "src"))

from tb4.core.maps import FREE, OCCUPIED, OccupancyMap, load_map, save_map  # noqa: E402

__all__ = ["Canvas", "draw_warehouse", "draw_depot", "draw_maze", "DRAWERS", "main"]

WORLDS_DIR = ROOT / "src" / "tb4" / "worlds"
BORDER = 0.2  # m, thickness of the walls lining every map
MAZE_SEED = 20240611


class Canvas:
    """An occupancy grid being drawn in map coordinates (row 0 = smallest y, like OccupancyMap.data)."""

    def __init__(self, resolution: float, origin: tuple[float, float], width: int, height: int) -> None:
        self.resolution = resolution
        self.origin = origin
        self.data = np.full((height, width), FREE, dtype=np.int8)
        self.xs = origin[0] + (np.arange(width) + 0.5) * resolution
        self.ys = origin[1] + (np.arange(height) + 0.5) * resolution

    @property
    def max_x(self) -> float:
        return self.origin[0] + self.data.shape[1] * self.resolution

    @property
    def max_y(self) -> float:
        return self.origin[1] + self.data.shape[0] * self.resolution

    def _window(self, x0: float, y0: float, x1: float, y1: float) -> tuple[slice, slice]:
        cols = np.nonzero((self.xs >= x0) & (self.xs <= x1))[0]
        rows = np.nonzero((self.ys >= y0) & (self.ys <= y1))[0]
        if cols.size == 0 or rows.size == 0:
            return slice(0, 0), slice(0, 0)
        return slice(rows[0], rows[-1] + 1), slice(cols[0], cols[-1] + 1)

    def rect(self, x0: float, y0: float, x1: float, y1: float, value: int = OCCUPIED) -> None:
        """Axis-aligned rectangle (cells whose centres lie inside)."""
        rs, cs = self._window(min(x0, x1), min(y0, y1), max(x0, x1), max(y0, y1))
        self.data[rs, cs] = value

    def _shape(self, cx: float, cy: float, r: float, inside: Callable[[np.ndarray, np.ndarray], np.ndarray]) -> None:
        rs, cs = self._window(cx - r, cy - r, cx + r, cy + r)
        dx = self.xs[cs][None, :] - cx
        dy = self.ys[rs][:, None] - cy
        self.data[rs, cs][inside(dx, dy)] = OCCUPIED

    def circle(self, cx: float, cy: float, r: float) -> None:
        self._shape(cx, cy, r, lambda dx, dy: dx * dx + dy * dy <= r * r)

    def ellipse(self, cx: float, cy: float, ax: float, ay: float) -> None:
        self._shape(cx, cy, max(ax, ay), lambda dx, dy: (dx / ax) ** 2 + (dy / ay) ** 2 <= 1.0)

    def box(self, cx: float, cy: float, length: float, width: float, heading_deg: float) -> None:
        """A rectangle of `length` along `heading_deg` and `width` across it."""
        c, s = math.cos(math.radians(heading_deg)), math.sin(math.radians(heading_deg))
        self._shape(
            cx,
            cy,
            0.5 * math.hypot(length, width),
            lambda dx, dy: (np.abs(dx * c + dy * s) <= length / 2) & (np.abs(-dx * s + dy * c) <= width / 2),
        )

    def hwall(
        self, y: float, x0: float, x1: float, t: float = 0.15, doors: tuple[tuple[float, float], ...] = ()
    ) -> None:
        """Horizontal wall centred on y from x0 to x1, with door openings (x_from, x_to)."""
        self._wall(x0, x1, doors, lambda a, b: self.rect(a, y - t / 2, b, y + t / 2))

    def vwall(
        self, x: float, y0: float, y1: float, t: float = 0.15, doors: tuple[tuple[float, float], ...] = ()
    ) -> None:
        """Vertical wall centred on x from y0 to y1, with door openings (y_from, y_to)."""
        self._wall(y0, y1, doors, lambda a, b: self.rect(x - t / 2, a, x + t / 2, b))

    @staticmethod
    def _wall(a: float, b: float, doors: tuple[tuple[float, float], ...], draw: Callable[[float, float], None]) -> None:
        start = a
        for d0, d1 in sorted(doors):
            if d0 > start:
                draw(start, d0)
            start = max(start, d1)
        if start < b:
            draw(start, b)

    def border(self, t: float = BORDER) -> None:
        x0, y0 = self.origin
        self.rect(x0, y0, self.max_x, y0 + t)
        self.rect(x0, self.max_y - t, self.max_x, self.max_y)
        self.rect(x0, y0, x0 + t, self.max_y)
        self.rect(self.max_x - t, y0, self.max_x, self.max_y)

    def dock_station(self) -> None:
        """The charging dock just ahead of the robot docked at (0, 0) facing +x."""
        self.rect(0.19, -0.20, 0.39, 0.20)

    def to_map(self) -> OccupancyMap:
        return OccupancyMap(
            data=self.data.copy(), resolution=self.resolution, origin_x=self.origin[0], origin_y=self.origin[1]
        )


def _rack_row_x(c: Canvas, y0: float, y1: float, x0: float, x1: float, bay: float = 2.7, post: float = 0.12) -> None:
    """A pallet rack running along x: solid beams on both long faces, uprights between bays, bays filled with stock."""
    c.rect(x0, y0, x1, y1)
    # Uprights stick out a little, as a lidar sees them.
    for x in np.arange(x0, x1 + 1e-9, bay):
        c.rect(x - post / 2, y0 - 0.04, x + post / 2, y1 + 0.04)


def _rack_row_y(c: Canvas, x0: float, x1: float, y0: float, y1: float, bay: float = 2.7, post: float = 0.12) -> None:
    """A pallet rack running along y."""
    c.rect(x0, y0, x1, y1)
    for y in np.arange(y0, y1 + 1e-9, bay):
        c.rect(x0 - 0.04, y - post / 2, x1 + 0.04, y + post / 2)


def _pillar(c: Canvas, x: float, y: float, side: float = 0.4) -> None:
    c.rect(x - side / 2, y - side / 2, x + side / 2, y + side / 2)


def draw_warehouse() -> OccupancyMap:
    """~30 x 50 m warehouse: racks in the south and north, an open floor with pillars around the dock, an office."""
    c = Canvas(0.03, (-15.1, -25.0), 1006, 1674)
    c.border(0.25)
    inner_w, inner_e, inner_n = -14.85, c.max_x - 0.25, c.max_y - 0.25

    # South block: racks running along y (x centres), aisles 2.4 m wide centred on x = ..., -5, ..., 9.4, ...
    # A cross aisle (y -16.2..-14.2) splits every row; the bottom cross aisle (y < -21.5) joins all aisles.
    for xc in (-10.4, -6.8, -3.2, 0.4, 4.0, 7.6, 11.2):
        for y0, y1 in ((-21.5, -16.2), (-14.2, -9.0)):
            _rack_row_y(c, xc - 0.6, xc + 0.6, y0, y1)
    for y0, y1 in ((-21.5, -16.2), (-14.2, -9.0)):
        _rack_row_y(c, inner_w, -13.6, y0, y1)  # single-sided racks against the walls
        _rack_row_y(c, 14.2, inner_e, y0, y1)

    # North block: racks running along x, aisles 2.3 m wide, a cross aisle at x -6.5..-3.5.
    rows = ((11.5, 12.7), (15.0, 16.2), (18.5, 19.7), (22.0, 23.2))
    for i, (y0, y1) in enumerate(rows):
        _rack_row_x(c, y0, y1, -13.5, -6.5)
        _rack_row_x(c, y0, y1, -3.5, 4.5)
        if i == 0:
            _rack_row_x(c, y0, y1, 7.5, 13.5)

    # Office corner (north-east): two rooms, desks, a meeting table.
    ox0, oy0 = 6.5, 17.5
    c.hwall(oy0, ox0, inner_e, doors=((9.0, 10.2),))
    c.vwall(ox0, oy0, inner_n, doors=((20.0, 21.0),))
    c.vwall(11.0, oy0, inner_n, doors=((18.2, 19.2),))
    for dy in (0.0, 2.6):
        c.rect(7.0, 22.2 - dy, 8.4, 22.9 - dy)  # desks along the west wall of the office
        c.rect(9.2, 22.2 - dy, 10.4, 22.9 - dy)
    c.ellipse(13.0, 21.6, 1.1, 0.6)  # meeting table
    c.rect(inner_e - 0.5, 18.0, inner_e, 19.6)  # cabinet

    # Open floor around the dock: structural pillars, packing tables on the west wall, parked pallets east.
    for x, y in ((-10.5, -5.5), (-6.5, -5.5), (-2.5, -5.5), (5.5, -5.5), (11.5, -5.5), (-2.5, 5.5), (7.5, 7.5)):
        _pillar(c, x, y)
    c.rect(inner_w, -6.5, -14.1, -3.5)  # packing table
    c.rect(inner_w, 4.0, -14.1, 6.5)  # packing table
    c.rect(13.4, -2.6, inner_e, -1.0)  # charging lockers on the east wall
    c.dock_station()
    return c.to_map()


def draw_depot() -> OccupancyMap:
    """~30 x 15 m depot hall: wood crate, steel barrels, a bathroom (with a toilet), racks, a small office."""
    c = Canvas(0.04, (-15.1, -7.74), 755, 380)
    c.border(BORDER)
    inner_w, inner_e, inner_s, inner_n = -14.9, c.max_x - BORDER, -7.54, c.max_y - BORDER

    # Racks along the north wall, leaving the middle of the hall open.
    _rack_row_x(c, inner_n - 0.8, inner_n, -14.0, -6.0)
    _rack_row_x(c, inner_n - 0.8, inner_n, 5.5, 14.0)

    # Wooden crate (destination 'wood crate' is at (0, 3), just south of it).
    c.rect(-0.5, 3.6, 0.5, 4.4)
    # Steel barrels (destination 'steel barrels' is at (2, 2)).
    for x, y in ((2.85, 2.6), (3.45, 2.45), (3.15, 3.15), (3.75, 3.05)):
        c.circle(x, y, 0.29)

    # Bathroom in the south-west: door in its east wall at y -6.5..-5.5; toilet and sink inside.
    c.vwall(-10.1, inner_s, -3.5)
    c.hwall(-3.5, -10.1, -6.5)
    c.vwall(-6.55, inner_s, -3.5, doors=((-6.5, -5.5),))
    c.rect(-10.0, -6.45, -9.8, -5.95)  # cistern
    c.ellipse(-9.5, -6.2, 0.3, 0.19)  # bowl
    c.rect(-8.4, -3.95, -7.8, -3.5)  # wash basin
    c.vwall(-8.9, inner_s, -6.9, t=0.05)  # stall partition

    # Small office in the south-east, door on its west side.
    c.vwall(9.0, inner_s, -2.5, doors=((-5.6, -4.6),))
    c.hwall(-2.5, 9.0, inner_e)
    c.rect(11.0, -7.4, 13.0, -6.7)  # desk
    c.rect(inner_e - 0.5, -5.5, inner_e, -3.5)  # shelf

    # Workbench on the west wall, stacked pallets in the south-west corner, a shelf island east, pillars.
    c.rect(inner_w, -2.0, -14.2, 1.0)
    c.rect(inner_w, inner_s, -13.6, -5.0)
    c.rect(-12.8, inner_s, -11.6, -6.4)
    _rack_row_x(c, 0.9, 1.7, 10.0, 14.0, bay=2.0)
    for x, y in ((-5.0, 2.0), (6.0, -1.0), (-11.0, 3.0)):
        _pillar(c, x, y, 0.36)
    c.dock_station()
    return c.to_map()


def _maze_walls(rng: np.random.Generator, n: int, room: int, extra_openings: int) -> tuple[np.ndarray, np.ndarray]:
    """A perfect maze on an n x n cell grid by randomized depth-first search, centre room x room cells open.

    Returns (east, north): east[i, j] True = wall between cell (i, j) and (i, j+1) (i = row/y, j = col/x).
    A few extra walls are removed afterwards so there are loops (several ways to a goal).
    """
    east = np.ones((n, n - 1), dtype=bool)
    north = np.ones((n - 1, n), dtype=bool)
    lo = (n - room) // 2
    hi = lo + room
    east[lo:hi, lo : hi - 1] = False
    north[lo : hi - 1, lo:hi] = False
    seen = np.zeros((n, n), dtype=bool)
    seen[lo:hi, lo:hi] = True
    # Carve from the room outwards: start at a cell beside the room and open the wall between them.
    stack = [(lo + room // 2, hi)]
    east[lo + room // 2, hi - 1] = False
    seen[stack[0]] = True
    while stack:
        i, j = stack[-1]
        options = [(i + di, j + dj) for di, dj in ((1, 0), (-1, 0), (0, 1), (0, -1))]
        options = [(a, b) for a, b in options if 0 <= a < n and 0 <= b < n and not seen[a, b]]
        if not options:
            stack.pop()
            continue
        a, b = options[int(rng.integers(len(options)))]
        if a != i:
            north[min(a, i), j] = False
        else:
            east[i, min(b, j)] = False
        seen[a, b] = True
        stack.append((a, b))
    # Open the room on its other three sides too, then add loops.
    east[lo + room // 2, lo - 1] = False
    north[hi - 1, lo + room // 2] = False
    north[lo - 1, lo + room // 2] = False
    walls_e = np.argwhere(east)
    walls_n = np.argwhere(north)
    for idx in rng.choice(len(walls_e), size=extra_openings, replace=False):
        east[tuple(walls_e[idx])] = False
    for idx in rng.choice(len(walls_n), size=extra_openings, replace=False):
        north[tuple(walls_n[idx])] = False
    return east, north


def draw_maze() -> OccupancyMap:
    """~20 x 20 m maze: 11 x 11 cells of 1.8 m (1.6 m corridors), an open 3 x 3-cell room around the dock."""
    c = Canvas(0.03, (-10.1, -10.0), 670, 669)
    c.border(BORDER)
    n, cell, t = 11, 1.8, 0.2
    lo = -n * cell / 2  # -9.9: cell boundaries at -9.9, -8.1, ..., 9.9; the dock (0, 0) is a cell centre
    east, north = _maze_walls(np.random.default_rng(MAZE_SEED), n, room=3, extra_openings=4)
    for i, j in np.argwhere(east):
        x = lo + (j + 1) * cell
        c.vwall(x, lo + i * cell - t / 2, lo + (i + 1) * cell + t / 2, t=t)
    for i, j in np.argwhere(north):
        y = lo + (i + 1) * cell
        c.hwall(y, lo + j * cell - t / 2, lo + (j + 1) * cell + t / 2, t=t)
    c.dock_station()
    return c.to_map()


DRAWERS: dict[str, Callable[[], OccupancyMap]] = {
    "warehouse": draw_warehouse,
    "depot": draw_depot,
    "maze": draw_maze,
}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("worlds", nargs="*", help=f"worlds to draw: {', '.join(DRAWERS)} (default: all)")
    parser.add_argument("--out", type=Path, default=WORLDS_DIR, help="output directory (default: %(default)s)")
    parser.add_argument("--check", action="store_true", help="compare with the files in --out instead of writing")
    args = parser.parse_args(argv)
    names = args.worlds or list(DRAWERS)
    unknown = [n for n in names if n not in DRAWERS]
    if unknown:
        parser.error(f"unknown world(s) {', '.join(unknown)}; choose from {', '.join(DRAWERS)}")
    status = 0
    for name in names:
        grid = DRAWERS[name]()
        target = args.out / f"{name}_map.yaml"
        if args.check:
            committed = load_map(target)
            same = committed.data.shape == grid.data.shape and bool(np.array_equal(committed.data, grid.data))
            print(f"{name}: {'up to date' if same else 'DIFFERS from ' + str(target)}")
            status |= 0 if same else 1
        else:
            args.out.mkdir(parents=True, exist_ok=True)
            save_map(grid, target)
            free = float(np.mean(grid.data == FREE))
            print(f"{name}: wrote {target} ({grid.width}x{grid.height} px, {free:.0%} free)")
    return status


if __name__ == "__main__":
    raise SystemExit(main())
