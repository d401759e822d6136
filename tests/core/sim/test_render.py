"""World pictures: every world renders to a valid PNG, and run overlays really get drawn."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from tb4.sim.render import render_world
from tb4.sim.world import World, load_world

pytestmark = pytest.mark.core


@pytest.fixture(scope="module")
def depot() -> World:
    return load_world("depot")


def _pixels(path: Path) -> np.ndarray:
    with Image.open(path) as img:
        assert img.format == "PNG"
        return np.asarray(img.convert("RGB")).astype(int)


def _count_color(pixels: np.ndarray, rgb: tuple[int, int, int], tol: int = 30) -> int:
    return int((np.abs(pixels - np.array(rgb)).max(axis=2) <= tol).sum())


@pytest.mark.parametrize("name", ["warehouse", "depot", "maze"])
def test_each_world_renders_a_png(tmp_path: Path, name: str) -> None:
    world = load_world(name)
    out = render_world(world, tmp_path / "sub" / f"{name}.png")
    assert out == tmp_path / "sub" / f"{name}.png"
    with Image.open(out) as img:
        img.verify()
    with Image.open(out) as img:
        width, height = img.size
    assert 400 <= max(width, height) <= 1200 and min(width, height) >= 300
    # Portrait for the 30 x 50 m warehouse, landscape for the 30 x 15 m depot.
    if name == "warehouse":
        assert height > width
    if name == "depot":
        assert width > height
    pixels = _pixels(out)
    assert _count_color(pixels, (0x2B, 0x2B, 0x2B), tol=8) > 1000  # walls drawn
    assert _count_color(pixels, (0x1F, 0x9E, 0x3A), tol=20) > 0  # the dock station


def test_run_overlays_are_drawn(tmp_path: Path, depot: World) -> None:
    plain = _pixels(render_world(depot, tmp_path / "plain.png"))
    t = np.linspace(0.0, 60.0, 120)
    trajectory = np.column_stack([t, -0.4 - 3.0 * t / 60.0, 5.5 * t / 60.0])
    plan = np.array([[-0.4, 0.0], [-2.0, 3.0], [-3.3, 5.9]])
    out = render_world(
        depot,
        tmp_path / "run.png",
        trajectory=trajectory,
        plans=[plan],
        goals=[(-3.3, 5.9, 0.0), (2.1, 6.3, math.pi / 2)],
        recoveries=[(-1.5, 2.0), (-2.5, 4.0)],
        robot_pose=(-3.3, 5.9, 0.0),
        title="follow waypoints",
        obstacle_time=10.0,
    )
    run = _pixels(out)
    assert run.shape[1] > plain.shape[1]  # the colorbar widens the figure
    assert _count_color(run, (0xE5, 0x39, 0x35), tol=25) > 20  # recovery X marks
    assert _count_color(plain, (0xE5, 0x39, 0x35), tol=25) == 0
    assert _count_color(run, (0xD8, 0x1B, 0x60), tol=25) > 20  # goal arrows
    assert _count_color(run, (0xFF, 0x98, 0x00), tol=25) > 10  # the planned path


def test_single_point_trajectory_and_empty_overlays(tmp_path: Path, depot: World) -> None:
    out = render_world(depot, tmp_path / "one.png", trajectory=np.array([[0.0, -0.4, 0.0]]), plans=(), goals=())
    assert _pixels(out).shape[2] == 3


def test_bad_trajectory_shape_is_refused(tmp_path: Path, depot: World) -> None:
    with pytest.raises(ValueError, match=r"\(N, >=3\)"):
        render_world(depot, tmp_path / "bad.png", trajectory=np.zeros((5, 2)))


def test_moving_obstacles_are_drawn_where_they_are_at_obstacle_time(tmp_path: Path, depot: World) -> None:
    mover = depot.moving_obstacles[0]
    a = _pixels(render_world(depot, tmp_path / "a.png", obstacle_time=0.0))
    b = _pixels(render_world(depot, tmp_path / "b.png", obstacle_time=7.0))
    assert mover.position_at(0.0) != mover.position_at(7.0)
    assert not np.array_equal(a, b)


def test_standing_still_draws_the_same_picture_as_the_segments_it_skips(tmp_path: Path, depot: World) -> None:
    """Hours on the dock are tens of thousands of zero-length segments: skipped, the picture keeps every pixel,
    time colours included (the scale spans the whole run, the still start and end too)."""
    import tb4.sim.render as render

    t = np.arange(0.0, 300.0, 0.2)
    moving = np.clip(t - 100.0, 0.0, 100.0)  # still for 100 s, drives for 100 s, still for 100 s
    trajectory = np.column_stack([t, -0.03 * moving, 0.05 * moving])
    segments = np.stack([trajectory[:-1, 1:3], trajectory[1:, 1:3]], axis=1)
    assert render._drawn_segments(segments).sum() == 500
    skipped = _pixels(render_world(depot, tmp_path / "skipped.png", trajectory=trajectory))
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(render, "_drawn_segments", lambda s: np.ones(len(s), dtype=bool))
        every = _pixels(render_world(depot, tmp_path / "every.png", trajectory=trajectory))
    assert np.array_equal(skipped, every)
