"""map_server maps: pixel interpretation (trinary, scale, raw, negate, alpha), orientation, errors, save/load."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from tb4.config import ConfigError
from tb4.core.maps import FREE, OCCUPIED, UNKNOWN, OccupancyMap, load_map, save_map

pytestmark = pytest.mark.core

# One row of gray levels: black, dark, mid, 205 (map_saver's unknown), light, 254 (free), white.
ROW = [0, 50, 128, 205, 220, 254, 255]


def _write_map(
    tmp_path: Path,
    pixels: np.ndarray,
    *,
    image_mode: str = "L",
    name: str = "m",
    suffix: str = ".pgm",
    extra: str = "",
    free_thresh: float = 0.196,
    occupied_thresh: float = 0.65,
    mode: str | None = "trinary",
    negate: int = 0,
) -> Path:
    image = tmp_path / f"{name}{suffix}"
    Image.fromarray(np.asarray(pixels, dtype=np.uint8), mode=image_mode).save(image)
    lines = [
        f"image: {image.name}",
        "resolution: 0.05",
        "origin: [-1.0, -2.0, 0.0]",
        f"negate: {negate}",
        f"occupied_thresh: {occupied_thresh}",
        f"free_thresh: {free_thresh}",
    ]
    if mode is not None:
        lines.append(f"mode: {mode}")
    yaml_path = tmp_path / f"{name}.yaml"
    yaml_path.write_text("\n".join(lines) + "\n" + extra, encoding="utf-8")
    return yaml_path


def test_trinary_thresholds(tmp_path: Path) -> None:
    grid = load_map(_write_map(tmp_path, np.array([ROW])))
    # occ = (255 - p) / 255: 1.0, 0.80, 0.50, 0.196 (not < 0.196 -> unknown), 0.14, 0.004, 0.0
    assert grid.data[0].tolist() == [OCCUPIED, OCCUPIED, UNKNOWN, UNKNOWN, FREE, FREE, FREE]
    assert grid.data.dtype == np.int8
    assert grid.resolution == 0.05 and (grid.origin_x, grid.origin_y, grid.origin_yaw) == (-1.0, -2.0, 0.0)


def test_trinary_with_free_thresh_025_reads_205_as_free(tmp_path: Path) -> None:
    """map_server semantics: with free_thresh 0.25 a 205 pixel (occ 0.196) is free. That is why save_map uses 0.196."""
    grid = load_map(_write_map(tmp_path, np.array([[205]]), free_thresh=0.25))
    assert grid.data[0, 0] == FREE


def test_mode_defaults_to_trinary(tmp_path: Path) -> None:
    grid = load_map(_write_map(tmp_path, np.array([ROW]), mode=None))
    assert grid.data[0].tolist() == [OCCUPIED, OCCUPIED, UNKNOWN, UNKNOWN, FREE, FREE, FREE]


def test_negate_swaps_black_and_white(tmp_path: Path) -> None:
    grid = load_map(_write_map(tmp_path, np.array([ROW]), negate=1))
    # occ = p / 255: 0.0, 0.196 (not < 0.196), 0.50, 0.80, 0.86, 0.996, 1.0
    assert grid.data[0].tolist() == [FREE, UNKNOWN, UNKNOWN, OCCUPIED, OCCUPIED, OCCUPIED, OCCUPIED]


def test_scale_mode_keeps_intermediate_values(tmp_path: Path) -> None:
    grid = load_map(_write_map(tmp_path, np.array([ROW]), mode="scale"))
    values = grid.data[0].tolist()
    assert values[0] == values[1] == OCCUPIED
    assert values[4:] == [FREE, FREE, FREE]
    assert 0 < values[2] < OCCUPIED  # occ 0.498 between the thresholds -> a cost, not unknown
    assert values[2] == pytest.approx(99 * (127 / 255 - 0.196) / (0.65 - 0.196), abs=1)
    assert 0 <= values[3] <= 1  # occ just at free_thresh -> ~0
    grid_tri = load_map(_write_map(tmp_path, np.array([ROW]), mode="trinary", name="t"))
    assert grid_tri.data[0, 2] == UNKNOWN


def test_scale_mode_transparent_pixels_are_unknown(tmp_path: Path) -> None:
    la = np.zeros((1, 3, 2), dtype=np.uint8)
    la[0, :, 0] = [0, 254, 254]
    la[0, :, 1] = [255, 255, 0]  # last pixel fully transparent
    path = _write_map(tmp_path, la, image_mode="LA", suffix=".png", mode="scale")
    assert load_map(path).data[0].tolist() == [OCCUPIED, FREE, UNKNOWN]


def test_raw_mode_uses_pixel_values(tmp_path: Path) -> None:
    grid = load_map(_write_map(tmp_path, np.array([[0, 37, 100, 101, 255]]), mode="raw"))
    assert grid.data[0].tolist() == [0, 37, 100, UNKNOWN, UNKNOWN]


def test_top_image_row_is_max_y(tmp_path: Path) -> None:
    pixels = np.full((4, 3), 254, dtype=np.uint8)
    pixels[0, 2] = 0  # top-right pixel in the image
    grid = load_map(_write_map(tmp_path, pixels))
    assert grid.data[3, 2] == OCCUPIED and grid.data[0, 2] == FREE
    # Cell (row 3, col 2) is the top-right corner of the map in world coordinates.
    x, y = grid.cell_to_world(3, 2)
    assert (x, y) == pytest.approx((-1.0 + 2.5 * 0.05, -2.0 + 3.5 * 0.05))
    assert grid.value_at(x, y) == OCCUPIED
    assert grid.value_at(-1.0 + 0.01, -2.0 + 0.01) == FREE
    assert grid.value_at(100.0, 0.0) == UNKNOWN  # off the map


def test_rgb_image_is_converted_to_gray(tmp_path: Path) -> None:
    rgb = np.zeros((1, 2, 3), dtype=np.uint8)
    rgb[0, 1] = 254
    grid = load_map(_write_map(tmp_path, rgb, image_mode="RGB", suffix=".png"))
    assert grid.data[0].tolist() == [OCCUPIED, FREE]


def test_absolute_image_path(tmp_path: Path) -> None:
    path = _write_map(tmp_path, np.array([[0, 254]]))
    other = tmp_path / "elsewhere"
    other.mkdir()
    text = path.read_text().replace("image: m.pgm", f"image: {tmp_path / 'm.pgm'}")
    (other / "abs.yaml").write_text(text)
    assert load_map(other / "abs.yaml").data[0].tolist() == [OCCUPIED, FREE]


def test_malformed_yaml(tmp_path: Path) -> None:
    path = tmp_path / "bad.yaml"
    path.write_text("image: [unclosed\nresolution: 0.05\n")
    with pytest.raises(ConfigError, match="not valid YAML") as info:
        load_map(path)
    assert info.value.source == str(path)
    path.write_text("- just\n- a list\n")
    with pytest.raises(ConfigError, match="mapping"):
        load_map(path)
    path.write_text("")
    with pytest.raises(ConfigError, match="empty"):
        load_map(path)


def test_missing_yaml_file(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match="file not found"):
        load_map(tmp_path / "nope.yaml")


@pytest.mark.parametrize("key", ["image", "resolution", "origin"])
def test_missing_required_key_is_named(tmp_path: Path, key: str) -> None:
    path = _write_map(tmp_path, np.array([[0]]))
    text = "\n".join(line for line in path.read_text().splitlines() if not line.startswith(f"{key}:"))
    path.write_text(text + "\n")
    with pytest.raises(ConfigError, match="required key is missing") as info:
        load_map(path)
    assert info.value.key == key


def test_misspelt_key_gets_a_suggestion(tmp_path: Path) -> None:
    path = _write_map(tmp_path, np.array([[0]]), extra="occupied_tresh: 0.7\n")
    with pytest.raises(ConfigError, match="did you mean 'occupied_thresh'") as info:
        load_map(path)
    assert info.value.key == "occupied_tresh"


@pytest.mark.parametrize(
    ("replace", "key", "fragment"),
    [
        (("resolution: 0.05", "resolution: fine"), "resolution", "number"),
        (("resolution: 0.05", "resolution: 0"), "resolution", ">="),
        (("origin: [-1.0, -2.0, 0.0]", "origin: [1, 2]"), "origin", "[x, y, yaw]"),
        (("origin: [-1.0, -2.0, 0.0]", "origin: [1, 2, nan]"), "origin[2]", "number"),
        (("negate: 0", "negate: 2"), "negate", "<= 1"),
        (("mode: trinary", "mode: ternary"), "mode", "trinary, scale or raw"),
        (("image: m.pgm", "image: 12"), "image", "image file name"),
    ],
)
def test_bad_values_name_the_key(tmp_path: Path, replace: tuple[str, str], key: str, fragment: str) -> None:
    path = _write_map(tmp_path, np.array([[0]]))
    path.write_text(path.read_text().replace(*replace))
    with pytest.raises(ConfigError) as info:
        load_map(path)
    assert info.value.key == key
    assert fragment in str(info.value)


def test_free_thresh_must_be_below_occupied_thresh(tmp_path: Path) -> None:
    for free in (0.7, 0.65):
        path = _write_map(tmp_path, np.array([[0]]), free_thresh=free, occupied_thresh=0.65)
        with pytest.raises(ConfigError, match="below occupied_thresh") as info:
            load_map(path)
        assert info.value.key == "free_thresh"


def test_missing_image(tmp_path: Path) -> None:
    path = _write_map(tmp_path, np.array([[0]]))
    (tmp_path / "m.pgm").unlink()
    with pytest.raises(ConfigError, match="image file not found") as info:
        load_map(path)
    assert info.value.key == "image"


def test_corrupt_image(tmp_path: Path) -> None:
    path = _write_map(tmp_path, np.array([[0]]))
    (tmp_path / "m.pgm").write_bytes(b"P5\n this is not an image")
    with pytest.raises(ConfigError, match="cannot read image") as info:
        load_map(path)
    assert info.value.key == "image"
    (tmp_path / "m.pgm").write_bytes(b"")
    with pytest.raises(ConfigError, match="cannot read image"):
        load_map(path)


def test_save_map_round_trip(tmp_path: Path) -> None:
    rng = np.random.default_rng(7)
    data = rng.choice(np.array([FREE, OCCUPIED, UNKNOWN], dtype=np.int8), size=(23, 31))
    grid = OccupancyMap(data, 0.03, origin_x=-15.1, origin_y=-25.0, origin_yaw=0.0)
    path = save_map(grid, tmp_path / "saved.yaml")
    assert path == tmp_path / "saved.yaml" and (tmp_path / "saved.pgm").is_file()
    back = load_map(path)
    assert np.array_equal(back.data, data)  # including unknown cells
    assert back.resolution == pytest.approx(0.03)
    assert (back.origin_x, back.origin_y, back.origin_yaw) == pytest.approx((-15.1, -25.0, 0.0))
    with Image.open(tmp_path / "saved.pgm") as img:
        assert img.size == (31, 23) and img.mode == "L"
        pixels = np.asarray(img)
    assert set(np.unique(pixels).tolist()) <= {0, 205, 254}
    assert pixels[0, 0] == {FREE: 254, OCCUPIED: 0, UNKNOWN: 205}[int(data[-1, 0])]  # top row = max y


def test_occupancy_map_geometry_and_validation() -> None:
    grid = OccupancyMap(np.zeros((10, 20)), 0.5, origin_x=1.0, origin_y=-2.0)
    assert (grid.width, grid.height) == (20, 10)
    assert grid.bounds == (1.0, -2.0, 11.0, 3.0)
    assert grid.world_to_cell(1.0, -2.0) == (0, 0)
    assert grid.world_to_cell(10.99, 2.99) == (9, 19)
    assert not grid.in_bounds(11.0, 0.0) and not grid.in_bounds(float("nan"), 0.0)
    grid.data[2, 3] = UNKNOWN
    grid.data[4, 5] = 70
    grid.data[4, 6] = 64
    mask = grid.occupied_mask()
    assert mask[2, 3] and mask[4, 5] and not mask[4, 6] and mask.sum() == 2
    with pytest.raises(ValueError):
        OccupancyMap(np.zeros((0, 3)), 0.05)
    with pytest.raises(ValueError):
        OccupancyMap(np.zeros((3, 3)), 0.0)
