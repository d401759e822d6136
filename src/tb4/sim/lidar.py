"""A 2D 360-degree lidar like the TurtleBot 4's RPLIDAR A1, fast enough to run many times faster than real time.

All beams are marched together through the static distance field (sphere tracing): each beam advances by a
step looked up from a precomputed table, the largest move that cannot enter an occupied cell from anywhere in
the current cell (field value minus one cell diagonal, at least half a cell; zero in occupied cells, which
freezes a beam on its hit). The last few slow beams (grazing walls) are finished by sampling every half cell, and
two bisection rounds then put each hit within 1/16 cell of the cell boundary. The marching runs in the small C
kernel tb4.sim._raymarch, the former NumPy march operation for operation (same ranges bit for bit; the NumPy
version took half of the simulator core's time). Circular (moving) obstacles are intersected analytically
afterwards. Beams that leave the map see nothing.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass

import numpy as np

from tb4.core.kernels import load_kernel
from tb4.core.robot_params import LidarParams
from tb4.sim.collision import Circles, DistanceField

__all__ = ["LaserScan", "Lidar", "lower_to_circle", "ray_circle_ranges"]


@dataclass(frozen=True)
class LaserScan:
    """One scan in the laser frame (robot centre, beam 0 along the robot's +x), like sensor_msgs/LaserScan."""

    ranges: np.ndarray  # float32, inf where nothing within range_max (or closer than range_min)
    angle_min: float
    angle_max: float
    angle_increment: float
    range_min: float
    range_max: float
    time: float


def lower_to_circle(
    out: np.ndarray,
    x: float,
    y: float,
    cos_a: np.ndarray,
    sin_a: np.ndarray,
    circle: tuple[float, float, float] | np.ndarray,
    beams: Iterable[int],
) -> None:
    """Lower `out` (ranges of the beams from (x, y) along cos_a, sin_a) where `beams` meet one circle (x, y, r):
    the first crossing of its surface; with the sensor inside, every beam reads 0. A circle that is not finite or
    has no size is nothing a beam can meet (a hostile peer pose, say): it is left out."""
    cx, cy, r = float(circle[0]), float(circle[1]), float(circle[2])
    dx, dy = cx - x, cy - y
    q = dx * dx + dy * dy - r * r  # < 0 when the sensor is inside
    if not (math.isfinite(q) and r > 0.0):
        return
    if q < 0.0:
        np.minimum(out, 0.0, out=out)
        return
    for i in beams:
        b = dx * float(cos_a[i]) + dy * float(sin_a[i])  # projection of the centre on the beam
        disc = b * b - q
        if disc >= 0.0:
            t = b - math.sqrt(disc)
            if 0.0 <= t < out[i]:
                out[i] = t


def ray_circle_ranges(
    x: float, y: float, cos_a: np.ndarray, sin_a: np.ndarray, circles: Circles | np.ndarray
) -> np.ndarray:
    """Distance along each beam from (x, y) to the first circle it meets (inf if none; 0 if inside one)."""
    out = np.full(len(cos_a), np.inf)
    for circle in circles:
        lower_to_circle(out, x, y, cos_a, sin_a, circle, range(len(out)))
    return out


class Lidar:
    """Ray caster over a DistanceField; one instance per robot, rebuilt tables on set_field()."""

    BISECTIONS = 2  # hits to 1/16 cell
    SPHERE_ITERATIONS = 64  # at most; stops earlier once few beams are left
    TAIL_BEAMS = 48  # when this few beams are left, finish them by chunked sampling
    TAIL_CHUNK = 2048  # samples per tail chunk, over all its beams
    TAIL_MAX_SAMPLES = 256  # half-cell samples per beam and chunk, at most

    def __init__(
        self, params: LidarParams, field: DistanceField, noise_seed: np.random.SeedSequence | int | None = None
    ) -> None:
        self._raymarch = load_kernel("tb4.sim._raymarch")
        self.params = params
        # Each scan's noise comes from (noise_seed, the scan's step) alone, never from a stream shared by every
        # reader: a scan read by a publisher, a viewer or nobody leaves the next scan's noise unchanged, so a run is
        # the same whoever listens, and `tb4 replay` (which has no publishers) reproduces it.
        if noise_seed is not None and not isinstance(noise_seed, np.random.SeedSequence):
            noise_seed = np.random.SeedSequence(noise_seed)
        self.noise_seed = noise_seed
        n = params.beams
        self.angle_min = 0.0
        self.angle_increment = 2.0 * math.pi / n
        self.angle_max = self.angle_min + (n - 1) * self.angle_increment
        angles = self.angle_min + np.arange(n) * self.angle_increment
        self._cos = np.cos(angles)
        self._sin = np.sin(angles)
        self.set_field(field)

    def set_field(self, field: DistanceField) -> None:
        """Precompute the step table for a (new) map.

        Steps are stored in half cells as uint8 (rounded down, so still safe; capped at 127 cells): a quarter of
        the memory of float32, which matters because every move reads a scattered cell. The table is the field
        padded further with occupied cells, so the tail sampling can read past the map edge unchecked.
        """
        self.field = field
        res = field.resolution
        d = field.dist
        # the same operations in the same order, in place: a warehouse map has 1.7 million cells, and each
        # temporary array cost a fresh process its page faults
        half_cells = d / res
        half_cells -= math.sqrt(2.0)
        np.maximum(half_cells, 0.5, out=half_cells)
        half_cells *= 2.0
        np.floor(half_cells, out=half_cells)
        half_cells[d <= 0.0] = 0.0
        np.minimum(half_cells, 255, out=half_cells)
        extra = self.TAIL_MAX_SAMPLES // 2 + 2
        self._table = np.zeros((d.shape[0] + 2 * extra, d.shape[1] + 2 * extra), dtype=np.uint8)
        self._table[extra:-extra, extra:-extra] = half_cells
        self._extra = extra
        # the map proper, in table cells: hits outside it are beams that left the map
        lo = extra + field.pad
        self._inside = (lo, lo, lo + field.width - 2 * field.pad, lo + field.height - 2 * field.pad)
        self._static_cache: tuple[tuple[float, float, float, int], np.ndarray] | None = None

    def ranges(self, x: float, y: float, yaw: float, circles: Circles | np.ndarray = ()) -> np.ndarray:
        """Noise-free ranges (float64, m) for a sensor at (x, y, yaw); inf when nothing is within range."""
        f = self.field
        res = f.resolution
        rmax = self.params.range_max
        cy_, sy_ = math.cos(yaw), math.sin(yaw)
        cos_a = cy_ * self._cos - sy_ * self._sin
        sin_a = sy_ * self._cos + cy_ * self._sin
        gx = (x - f.origin_x) / res  # sensor in cell units of the padded field
        gy = (y - f.origin_y) / res
        key = (x, y, yaw, id(f))
        if self._static_cache is not None and self._static_cache[0] == key:
            out = self._static_cache[1].copy()  # a robot standing still (docked, charging) sees the same walls
        elif not (0.0 <= gx < f.width and 0.0 <= gy < f.height):
            out = np.full(cos_a.shape, np.inf)
        else:
            out = self._march(gx + self._extra, gy + self._extra, cos_a, sin_a) * res
        self._static_cache = (key, out.copy())
        for circle in circles:
            self._intersect_circle(out, x, y, yaw, cos_a, sin_a, circle)
        out[(out > rmax) | (out < self.params.range_min)] = np.inf
        return out

    def _intersect_circle(
        self,
        out: np.ndarray,
        x: float,
        y: float,
        yaw: float,
        cos_a: np.ndarray,
        sin_a: np.ndarray,
        circle: tuple[float, float, float] | np.ndarray,
    ) -> None:
        """lower_to_circle on only the beams that can meet the circle: one wholly beyond range_max is never seen
        (most scans meet none); one 10 m away spans a few beams of 360 (taken with two more on each side)."""
        cx, cy, r = float(circle[0]), float(circle[1]), float(circle[2])
        d = math.hypot(cx - x, cy - y)
        if not d - r < self.params.range_max:  # beyond it, or not finite
            return
        if d <= r:  # the sensor inside (or on the surface): every beam
            lower_to_circle(out, x, y, cos_a, sin_a, circle, range(len(out)))
            return
        n = len(out)
        centre = (math.atan2(cy - y, cx - x) - yaw - self.angle_min) / self.angle_increment
        half = math.asin(r / d) / self.angle_increment + 2.0
        beams = (k % n for k in range(math.floor(centre - half), math.ceil(centre + half) + 1))
        lower_to_circle(out, x, y, cos_a, sin_a, circle, beams)

    def _march(self, gx: float, gy: float, cos_a: np.ndarray, sin_a: np.ndarray) -> np.ndarray:
        """Distance in cells to the first occupied cell along each beam (inf for none within range / off-map);
        (gx, gy) is the sensor in table cells."""
        out = np.empty(cos_a.shape, dtype=np.float64)
        height, width = self._table.shape
        limit = self.params.range_max / self.field.resolution
        self._raymarch.march(
            self._table,
            width,
            height,
            gx,
            gy,
            np.ascontiguousarray(cos_a, dtype=np.float64),
            np.ascontiguousarray(sin_a, dtype=np.float64),
            limit,
            self._inside,
            (self.SPHERE_ITERATIONS, self.TAIL_BEAMS, self.TAIL_CHUNK, self.TAIL_MAX_SAMPLES, self.BISECTIONS),
            out,
        )
        return out

    def noise_generator(self, step: int) -> np.random.Generator:
        """The generator of the noise of the scan taken at physics step `step` (a function of the seed and step)."""
        assert self.noise_seed is not None
        seq = self.noise_seed
        return np.random.default_rng(np.random.SeedSequence(seq.entropy, spawn_key=(*seq.spawn_key, int(step))))

    def scan(
        self, x: float, y: float, yaw: float, time: float, circles: Circles = (), noise: bool = False, step: int = 0
    ) -> LaserScan:
        """A LaserScan at pose (x, y, yaw); with `noise`, an RPLIDAR's faults, seeded by (noise_seed, `step`):
        Gaussian range noise (kept within [range_min, range_max]) and dropouts (beams that return inf)."""
        r = self.ranges(x, y, yaw, circles)
        p = self.params
        if noise and self.noise_seed is not None:
            rng = self.noise_generator(step)
            if p.noise_stddev > 0.0:
                finite = np.isfinite(r)
                r = r + rng.normal(0.0, p.noise_stddev, size=r.shape)
                r[finite] = np.clip(r[finite], p.range_min, p.range_max)
            if p.dropout_probability > 0.0:
                r[rng.random(r.shape) < p.dropout_probability] = np.inf
        return LaserScan(
            ranges=r.astype(np.float32),
            angle_min=self.angle_min,
            angle_max=self.angle_max,
            angle_increment=self.angle_increment,
            range_min=p.range_min,
            range_max=p.range_max,
            time=time,
        )
