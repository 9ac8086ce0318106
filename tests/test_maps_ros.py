"""ROS map_server maps as ground truth: pixel rules, orientation, located errors, start poses."""
from __future__ import annotations

import math
import os
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from PIL import Image
from scipy import ndimage

from world_sim.map_spec import (
    MapSpecError,
    clearance_field_m,
    default_start,
    resolve_map,
    staging_poses,
)
from world_sim.occupancy_map import OccupancyMap
from world_sim.ros_map import MapFormatError, body_fits, load_ros_map, reachable_area_m2, reachable_free

DATA = Path(__file__).parent / "data"
SHARED_MAPS = Path(os.environ.get("LORASCOUT_MAPS", Path(__file__).resolve().parents[2] / "shared" / "maps"))

# file, image (cols, rows), resolution, README "free, reachable" m2
SHARED = [
    ("depot.yaml", (604, 307), 0.05, 437.0),
    ("intel.yaml", (888, 848), 0.05, 513.0),
    ("willow.yaml", (540, 587), 0.1, 1300.0),
    ("maze_a.yaml", (500, 500), 0.2, 3700.0),
    ("maze_b.yaml", (500, 500), 0.2, 4200.0),
]


def write_map(folder: Path, pixels: np.ndarray, image_name: str = "m.png", yaml_name: str = "m.yaml",
              **fields) -> Path:
    """Save pixels (rows top-down, as in the image file) and a YAML naming them."""
    pixels = np.asarray(pixels, dtype=np.uint8)
    image_path = folder / image_name
    if image_name.endswith(".pgm") and fields.pop("plain", False):
        body = "\n".join(" ".join(str(int(v)) for v in row) for row in pixels)
        image_path.write_text(f"P2\n{pixels.shape[1]} {pixels.shape[0]}\n255\n{body}\n")
    else:
        Image.fromarray(pixels).save(image_path)
    doc = {"image": image_name, "resolution": 0.1, "origin": "[0.0, 0.0, 0.0]", "negate": 0,
           "occupied_thresh": 0.65, "free_thresh": 0.196}
    doc.update(fields)
    text = "".join(f"{k}: {v}\n" for k, v in doc.items() if v is not None)
    path = folder / yaml_name
    path.write_text(text)
    return path


def reference_free(pixels: np.ndarray, mode: str, negate: bool, free_thresh: float) -> np.ndarray:
    """map_server's per-pixel rule written out plainly, top row first (as in the file)."""
    px = np.asarray(pixels, dtype=np.float64)
    if px.ndim == 2:
        px = px[:, :, None]
    rows, cols, channels = px.shape
    out = np.zeros((rows, cols), dtype=bool)
    for r in range(rows):
        for c in range(cols):
            values = list(px[r, c])
            if channels == 2:  # grey + alpha is read as RGBA
                values = [values[0], values[0], values[0], values[1]]
            if len(values) == 4 and mode != "trinary":
                values = values[:3]
            avg = sum(values) / len(values)
            if negate:
                avg = 255.0 - avg
            if mode == "raw":
                v = round(avg)
                out[r, c] = v <= 100 and v / 100.0 < free_thresh
            else:
                out[r, c] = (255.0 - avg) / 255.0 < free_thresh
    return out


# ----------------------------------------------------------------------------- shared maps


@pytest.mark.parametrize("name,size,resolution,readme_m2", SHARED)
def test_shared_maps_load_with_readme_areas(name, size, resolution, readme_m2):
    path = SHARED_MAPS / name
    if not path.exists():
        pytest.skip(f"shared map {path} not present")
    occ = load_ros_map(path)
    assert (occ.cols, occ.rows) == size
    assert occ.resolution_m == pytest.approx(resolution)
    assert occ.name == name
    start = default_start(occ)
    assert occ.is_free_point(start[0], start[1])
    # the README figures are the 4-connected component; 8-connected leaks through diagonal chinks
    assert reachable_area_m2(occ, start[:2], connectivity=4) == pytest.approx(readme_m2, rel=0.01)
    area8 = reachable_area_m2(occ, start[:2])
    assert readme_m2 <= area8 <= readme_m2 * 1.05
    # image row 0 is the top: the loaded grid must be the flipped image
    raw = np.asarray(Image.open(path.parent / load_image_name(path)).convert("L"))
    occupancy = (255.0 - raw) / 255.0
    free_thresh = {"depot.yaml": 0.25, "intel.yaml": 0.1, "willow.yaml": 0.1}.get(name, 0.3)
    np.testing.assert_array_equal(occ.free, np.flipud(occupancy < free_thresh))


def load_image_name(yaml_path: Path) -> str:
    for line in yaml_path.read_text().splitlines():
        if line.startswith("image:"):
            return line.split(":", 1)[1].strip()
    raise AssertionError("no image line")


def test_tiny_room_fixture_orientation_origin_and_threshold():
    occ = load_ros_map(DATA / "tiny_room.yaml")
    assert (occ.rows, occ.cols) == (6, 8)
    assert (occ.origin_x_m, occ.origin_y_m, occ.resolution_m) == (-2.0, 1.0, 0.5)
    # file row 1 (second from top) is grid row 4; file row 4 has a wall at col 6 -> grid row 1
    assert occ.free[4, 1:7].all()
    assert not occ.free[1, 6] and occ.free[1, 5]
    # 205 is exactly at p = 0.19608 >= free_thresh 0.196: unknown, so wall; 208 (p=0.184) free
    assert not occ.free[3, 5]
    assert occ.free[2:4, 2:4].all()
    assert not occ.free[0].any() and not occ.free[-1].any()
    # world coordinates: cell (row 2, col 2) covers x -1.0..-0.5, y 2.0..2.5
    assert occ.cell_of(-0.75, 2.25) == (2, 2)
    assert occ.is_free_point(-0.75, 2.25) and not occ.is_free_point(-1.9, 1.1)


def test_plain_and_binary_pgm_and_png_agree(tmp_path):
    rng = np.random.default_rng(5)
    pixels = rng.choice(np.array([0, 100, 205, 230, 254], dtype=np.uint8), size=(7, 9))
    p2 = load_ros_map(write_map(tmp_path, pixels, "a.pgm", "a.yaml", plain=True))
    p5 = load_ros_map(write_map(tmp_path, pixels, "b.pgm", "b.yaml"))
    png = load_ros_map(write_map(tmp_path, pixels, "c.png", "c.yaml"))
    assert (tmp_path / "a.pgm").read_bytes().startswith(b"P2")
    assert (tmp_path / "b.pgm").read_bytes().startswith(b"P5")
    expected = np.flipud(reference_free(pixels, "trinary", False, 0.196))
    for occ in (p2, p5, png):
        np.testing.assert_array_equal(occ.free, expected)
    assert expected.any() and not expected.all()


def test_sixteen_bit_pgm_is_scaled(tmp_path):
    header = b"P5\n3 1\n65535\n"
    (tmp_path / "w.pgm").write_bytes(header + np.array([0, 65535, 60000], ">u2").tobytes())
    occ = load_ros_map(write_map(tmp_path, np.zeros((1, 1)), "unused.png", "w.yaml", image="w.pgm"))
    # 60000/257 = 233.5 -> p = 0.084 < 0.196 free; 0 -> wall
    np.testing.assert_array_equal(occ.free, [[False, True, True]])


def test_negate_flips_free_and_wall(tmp_path):
    pixels = np.array([[0, 254], [128, 20]], dtype=np.uint8)
    plain = load_ros_map(write_map(tmp_path, pixels, "p.png", "p.yaml", negate=0))
    flipped = load_ros_map(write_map(tmp_path, pixels, "n.png", "n.yaml", negate=1))
    np.testing.assert_array_equal(plain.free, np.flipud([[False, True], [False, False]]))
    np.testing.assert_array_equal(flipped.free, np.flipud([[True, False], [False, True]]))
    # YAML booleans are accepted too
    as_bool = load_ros_map(write_map(tmp_path, pixels, "b.png", "b.yaml", negate="true"))
    np.testing.assert_array_equal(as_bool.free, flipped.free)


def test_free_threshold_is_strict_and_moves_the_boundary(tmp_path):
    pixels = np.array([[255, 230, 204, 128]], dtype=np.uint8)  # p = 0, 0.098, 0.2, 0.498
    def free_for(ft, ot=0.9):
        return load_ros_map(write_map(tmp_path, pixels, "t.png", "t.yaml", free_thresh=ft,
                                      occupied_thresh=ot)).free[0].tolist()
    assert free_for(0.05) == [True, False, False, False]
    assert free_for(0.2) == [True, True, False, False]  # p = 0.2 is not below 0.2
    assert free_for(0.5) == [True, True, True, True]


def test_rgb_channels_are_averaged(tmp_path):
    # (255, 255, 0) averages to 170: p = 0.333, wall at free_thresh 0.3; (255,255,200) -> free
    pixels = np.array([[[255, 255, 0], [255, 255, 200], [0, 0, 255]]], dtype=np.uint8)
    occ = load_ros_map(write_map(tmp_path, pixels, free_thresh=0.3))
    assert occ.free[0].tolist() == [False, True, False]


def test_alpha_is_averaged_in_trinary_but_not_in_scale(tmp_path):
    # white with alpha 0: trinary averages (255,255,255,0) = 191 -> p 0.25 -> wall at 0.2
    pixels = np.array([[[255, 255, 255, 0], [255, 255, 255, 255]]], dtype=np.uint8)
    trinary = load_ros_map(write_map(tmp_path, pixels, "a.png", "a.yaml", free_thresh=0.2))
    scale = load_ros_map(write_map(tmp_path, pixels, "b.png", "b.yaml", free_thresh=0.2, mode="scale"))
    assert trinary.free[0].tolist() == [False, True]
    assert scale.free[0].tolist() == [True, True]


def test_raw_mode_reads_occupancy_percent(tmp_path):
    # raw: the value is the occupancy in percent; > 100 is unknown
    pixels = np.array([[0, 10, 30, 100, 101, 255]], dtype=np.uint8)
    occ = load_ros_map(write_map(tmp_path, pixels, mode="raw", free_thresh=0.25))
    assert occ.free[0].tolist() == [True, True, False, False, False, False]
    negated = load_ros_map(write_map(tmp_path, 255 - pixels, "n.png", "n.yaml", mode="raw",
                                     free_thresh=0.25, negate=1))
    np.testing.assert_array_equal(negated.free, occ.free)


def test_palette_and_bilevel_images(tmp_path):
    grey = np.array([[0, 255], [255, 0]], dtype=np.uint8)
    Image.fromarray(grey).convert("P").save(tmp_path / "p.png")
    Image.fromarray(grey).convert("1").save(tmp_path / "b.png")
    for name in ("p.png", "b.png"):
        occ = load_ros_map(write_map(tmp_path, grey, "unused.png", name + ".yaml", image=name))
        np.testing.assert_array_equal(occ.free, np.flipud(grey == 255))


def test_absolute_and_subfolder_image_paths(tmp_path):
    sub = tmp_path / "img"
    sub.mkdir()
    pixels = np.array([[254, 0]], dtype=np.uint8)
    Image.fromarray(pixels).save(sub / "x.png")
    rel = load_ros_map(write_map(tmp_path, pixels, "unused.png", "r.yaml", image="img/x.png"))
    other = tmp_path / "elsewhere"
    other.mkdir()
    absolute = load_ros_map(write_map(other, pixels, "unused.png", "a.yaml", image=str(sub / "x.png")))
    assert rel.free.tolist() == absolute.free.tolist() == [[True, False]]


def test_numeric_strings_are_read_like_yaml_cpp(tmp_path):
    occ = load_ros_map(write_map(tmp_path, np.full((2, 2), 254), resolution="5e-2",
                                 origin="['1.5', -2, 0]"))
    assert occ.resolution_m == pytest.approx(0.05)
    assert (occ.origin_x_m, occ.origin_y_m) == (1.5, -2.0)


@settings(max_examples=40, deadline=None)
@given(
    data=st.data(),
    channels=st.sampled_from([1, 2, 3, 4]),
    mode=st.sampled_from(["trinary", "scale", "raw"]),
    negate=st.booleans(),
    free_thresh=st.floats(0.0, 0.9),
)
def test_loader_matches_reference_rule(tmp_path_factory, data, channels, mode, negate, free_thresh):
    rows = data.draw(st.integers(1, 6))
    cols = data.draw(st.integers(1, 6))
    shape = (rows, cols) if channels == 1 else (rows, cols, channels)
    flat = data.draw(st.lists(st.integers(0, 255), min_size=int(np.prod(shape)), max_size=int(np.prod(shape))))
    pixels = np.array(flat, dtype=np.uint8).reshape(shape)
    folder = tmp_path_factory.mktemp("hyp")
    occ = load_ros_map(write_map(folder, pixels, mode=mode, negate=int(negate),
                                 free_thresh=repr(free_thresh), occupied_thresh=0.95))
    np.testing.assert_array_equal(occ.free, np.flipud(reference_free(pixels, mode, negate, free_thresh)))


# ----------------------------------------------------------------------------- errors


def error_of(path) -> str:
    with pytest.raises(MapFormatError) as info:
        load_ros_map(path)
    assert isinstance(info.value, ValueError)
    return str(info.value)


def test_fixture_errors_name_file_line_and_field():
    assert error_of(DATA / "bad_resolution.yaml") == (
        "bad_resolution.yaml:3: field 'resolution': expected a positive number, got 'abc'"
    )
    msg = error_of(DATA / "rotated_origin.yaml")
    assert msg.startswith("rotated_origin.yaml:3: field 'origin': rotated origins are unsupported")
    msg = error_of(DATA / "malformed.yaml")
    assert msg.startswith("malformed.yaml:4: malformed YAML") and "line 3" in msg
    msg = error_of(DATA / "corrupt_image.yaml")
    assert msg.startswith("corrupt_image.yaml:3: field 'image': cannot decode image")
    assert "corrupt.png" in msg


def test_missing_yaml_file(tmp_path):
    msg = error_of(tmp_path / "nothere.yaml")
    assert "nothere.yaml" in msg and "not found" in msg


def test_empty_and_non_mapping_yaml(tmp_path):
    (tmp_path / "e.yaml").write_text("")
    assert error_of(tmp_path / "e.yaml").startswith("e.yaml: empty map YAML")
    (tmp_path / "l.yaml").write_text("\n- 1\n- 2\n")
    assert error_of(tmp_path / "l.yaml").startswith("l.yaml:2: expected a mapping")


def test_missing_fields_are_named(tmp_path):
    path = write_map(tmp_path, np.zeros((2, 2)), resolution=None, free_thresh=None)
    msg = error_of(path)
    assert msg.startswith("m.yaml:1: missing required fields")
    assert "'resolution'" in msg and "'free_thresh'" in msg and "'origin'" not in msg


@pytest.mark.parametrize(
    "field,value,line,expect",
    [
        ("resolution", "-0.1", 2, "expected a positive number, got -0.1"),
        ("resolution", "[1]", 2, "expected a positive number"),
        ("resolution", ".nan", 2, "expected a positive number"),
        ("resolution", "true", 2, "expected a positive number, got True"),
        ("origin", "[0, 0]", 3, "expected [x, y, yaw]"),
        ("origin", "[0, north, 0]", 3, "y must be a number, got 'north'"),
        ("origin", "[0, 0, 0.1]", 3, "rotated origins are unsupported"),
        ("negate", "2", 4, "expected 0 or 1, got 2"),
        ("occupied_thresh", "1.5", 5, "expected a number in [0, 1], got 1.5"),
        ("free_thresh", "-0.1", 6, "expected a number in [0, 1], got -0.1"),
        ("free_thresh", "0.7", 6, "must be below occupied_thresh (0.65), got 0.7"),
        ("image", "[a, b]", 1, "expected an image file name"),
        ("image", "nope.png", 1, "image file not found"),
        ("mode", "ternary", 7, "expected one of trinary, scale, raw, got 'ternary'"),
    ],
)
def test_bad_field_messages(tmp_path, field, value, line, expect):
    fields = {"mode": "trinary", field: value}
    path = write_map(tmp_path, np.zeros((2, 2)), **fields)
    msg = error_of(path)
    assert msg.startswith(f"m.yaml:{line}: field '{field}': ")
    assert expect in msg
    if field == "image" and value == "nope.png":
        assert str(tmp_path / "nope.png") in msg


def test_duplicate_key_is_reported_with_both_lines(tmp_path):
    path = write_map(tmp_path, np.zeros((2, 2)))
    path.write_text(path.read_text() + "resolution: 0.2\n")
    assert error_of(path) == "m.yaml:7: field 'resolution': duplicate key (first at line 2)"


def test_truncated_image_names_the_image(tmp_path):
    path = write_map(tmp_path, np.full((40, 40), 254), "t.png", "t.yaml")
    data = (tmp_path / "t.png").read_bytes()
    (tmp_path / "t.png").write_bytes(data[: len(data) // 2])
    msg = error_of(path)
    assert msg.startswith("t.yaml:1: field 'image': cannot decode image") and "t.png" in msg


def test_directory_as_yaml_path(tmp_path):
    assert "cannot read map YAML" in error_of(tmp_path)


# ----------------------------------------------------------------------------- reachability


def grid_map(rows_text: list[str], resolution_m: float = 1.0) -> OccupancyMap:
    """'.' free, '#' wall; first string is the top row (highest y)."""
    free = np.array([[ch == "." for ch in row] for row in rows_text[::-1]])
    return OccupancyMap(free=free, resolution_m=resolution_m, origin_x_m=0.0, origin_y_m=0.0)


def test_reachable_free_eight_vs_four_connected():
    occ = grid_map([
        "#####",
        "#..##",
        "#..##",
        "###.#",
        "#####",
    ])
    eight = reachable_free(occ, (1.5, 2.5))
    four = reachable_free(occ, (1.5, 2.5), connectivity=4)
    assert eight.sum() == 5 and four.sum() == 4
    assert reachable_area_m2(occ, (1.5, 2.5)) == 5.0
    with pytest.raises(ValueError, match="connectivity must be 4 or 8"):
        reachable_free(occ, (1.5, 2.5), connectivity=6)


def test_reachable_free_rejects_bad_starts():
    occ = grid_map(["###", "#.#", "###"])
    with pytest.raises(ValueError, match="outside map"):
        reachable_free(occ, (5.0, 1.0))
    with pytest.raises(ValueError, match="wall cell"):
        reachable_free(occ, (0.5, 0.5))


# ----------------------------------------------------------------------------- start poses


def test_default_start_is_most_open_cell_of_largest_component():
    occ = grid_map([
        "############",
        "#...#......#",
        "#...#......#",
        "#...#......#",
        "#####......#",
        "#####......#",
        "############",
    ])
    x, y, yaw = default_start(occ)
    row, col = occ.cell_of(x, y)
    assert occ.free[row, col]
    assert 5 <= col <= 10  # right room, the largest
    clearance = clearance_field_m(occ.free, 1.0)
    right_room = clearance[:, 5:]
    assert clearance[row, col] == right_room.max()
    # ties go to the lowest row, then column
    best = np.argwhere(clearance == right_room.max())
    assert (row, col) == tuple(min(map(tuple, best)))
    assert default_start(occ) == (x, y, yaw)
    assert 0.0 <= yaw < 2 * math.pi


def test_default_start_faces_the_long_corridor():
    rows = ["#" * 40] + ["#" + "." * 38 + "#"] * 3 + ["#" * 40]
    occ = grid_map(rows, resolution_m=0.5)
    x, y, yaw = default_start(occ)
    assert yaw == 0.0 or yaw == pytest.approx(math.pi)


def test_default_start_on_a_wall_only_map_raises():
    with pytest.raises(ValueError, match="no free cell"):
        default_start(grid_map(["###", "###"]))


def test_staging_poses_are_spaced_roomy_and_connected():
    occ = load_ros_map(DATA / "tiny_room.yaml")
    big = OccupancyMap(free=np.kron(occ.free, np.ones((10, 10), dtype=bool)), resolution_m=0.05,
                       origin_x_m=0.0, origin_y_m=0.0)
    start = default_start(big)
    poses = staging_poses(big, start, 4, spacing_m=0.5, clearance_m=0.3)
    assert len(poses) == 4 and poses[0] == start
    clearance = clearance_field_m(big.free, big.resolution_m)
    comp = reachable_free(big, start[:2])
    for i, (x, y, yaw) in enumerate(poses):
        r, c = big.cell_of(x, y)
        assert clearance[r, c] >= 0.3 and comp[r, c] and yaw == start[2]
        for x2, y2, _ in poses[i + 1:]:
            assert math.hypot(x - x2, y - y2) >= 0.5 - 1e-9
    assert staging_poses(big, start, 4, spacing_m=0.5, clearance_m=0.3) == poses
    with pytest.raises(ValueError, match="only .* of 40 staging poses"):
        staging_poses(big, start, 40, spacing_m=0.5, clearance_m=0.3)
    assert staging_poses(big, start, 0) == []


def test_staging_poses_stay_on_the_start_side_of_a_wall():
    rows = ["#" * 23] + ["#" + "." * 10 + "#" + "." * 10 + "#"] * 9 + ["#" * 23]
    occ = grid_map(rows, resolution_m=0.5)
    start = (2.75, 2.75, 0.0)
    poses = staging_poses(occ, start, 10, spacing_m=1.0, clearance_m=0.5)
    assert all(x < 5.5 for x, _, _ in poses)  # never through the wall at x = 5.5..6.0
    with pytest.raises(ValueError, match="not on a free cell"):
        staging_poses(occ, (5.75, 2.75, 0.0), 3)


def test_staging_poses_from_a_cramped_start_move_to_roomy_cells():
    rows = ["#" * 14, "#." + "#" * 12] + ["#" + "." * 12 + "#"] * 6 + ["#" * 14]
    occ = grid_map(rows, resolution_m=0.5)
    start = (0.75, 3.75, 0.0)  # the one-cell nook at the top left
    poses = staging_poses(occ, start, 3, spacing_m=1.0, clearance_m=0.5)
    assert poses[0] != start and len(poses) == 3
    clearance = clearance_field_m(occ.free, 0.5)
    assert all(clearance[occ.cell_of(x, y)] >= 0.5 for x, y, _ in poses)


# ----------------------------------------------------------------------------- map specs


def test_resolve_yaml_spec():
    occ, start, label = resolve_map(str(DATA / "tiny_room.yaml"))
    assert label == "tiny_room.yaml" and occ.is_free_point(start[0], start[1])
    assert start == default_start(occ)


@pytest.mark.parametrize(
    "spec,expect",
    [
        ("", "empty map spec"),
        ("maze", "unrecognised map spec 'maze'"),
        ("cave:x", "seed 'x' is not a non-negative integer"),
        ("cave:-1", "seed '-1' is not a non-negative integer"),
        ("tunnel:1:100", "size '100' is not WxH in metres"),
        ("cave:1:10x100", "width 10 m is outside"),
        ("cave:1:100x9000", "height 9000 m is outside"),
        ("cave:1:2:3:4", "separators"),
    ],
)
def test_bad_specs_say_what_is_wrong_and_what_is_accepted(spec, expect):
    with pytest.raises(MapSpecError) as info:
        resolve_map(spec)
    assert expect in str(info.value)
    assert "accepted:" in str(info.value) or "outside" in str(info.value)


def test_yaml_spec_errors_keep_their_location(tmp_path):
    with pytest.raises(MapFormatError, match=r"bad_resolution.yaml:3: field 'resolution'"):
        resolve_map(str(DATA / "bad_resolution.yaml"))


def test_clearance_treats_outside_as_wall():
    occ = grid_map(["...", "..."], resolution_m=1.0)
    clearance = clearance_field_m(occ.free, 1.0)
    assert clearance.max() == pytest.approx(0.5)
    assert ndimage.label(occ.free)[1] == 1


def test_resolution_and_size_are_bounded_before_allocation(tmp_path):
    """Issue 27: `resolution: 1e-9` asked for 149 GiB; an image's cells are counted from its
    header, before its pixels are decoded, and the error estimates what it would cost."""
    from PIL import Image

    from world_sim.ros_map import MAX_CELLS

    fields = "origin: [0, 0, 0]\nnegate: 0\noccupied_thresh: 0.65\nfree_thresh: 0.196\n"
    Image.new("L", (20, 20), 254).save(tmp_path / "small.png")
    for resolution in ("1e-9", "0.001", "5"):
        (tmp_path / "r.yaml").write_text(f"image: small.png\nresolution: {resolution}\n{fields}")
        with pytest.raises(MapFormatError, match=r"r.yaml:2: field 'resolution': .* m per cell is outside 0.01..1 m"):
            load_ros_map(tmp_path / "r.yaml")
    Image.new("1", (9000, 8000), 1).save(tmp_path / "big.png")
    assert 9000 * 8000 > MAX_CELLS
    (tmp_path / "big.yaml").write_text(f"image: big.png\nresolution: 0.05\n{fields}")
    with pytest.raises(MapFormatError) as info:
        load_ros_map(tmp_path / "big.yaml")
    msg = str(info.value)
    assert msg.startswith("big.yaml:1: field 'image':") and "9000 x 8000 pixels (450 x 400 m" in msg
    assert "72000000 cells" in msg and "GiB for one robot" in msg and f"at most {MAX_CELLS} cells" in msg


def test_deeply_nested_yaml_is_an_error_not_a_crash(tmp_path):
    (tmp_path / "deep.yaml").write_text("image: " + "[" * 50_000 + "\n")
    with pytest.raises(MapFormatError, match="nested too deeply"):
        load_ros_map(tmp_path / "deep.yaml")


@pytest.mark.parametrize("door_cells, passes", [(5, False), (6, True), (7, True)])
def test_the_body_reaches_through_a_door_the_world_lets_it_through(door_cells, passes):
    """A 0.5 m body (2.5 cells) fits a door of 6 cells at its middle, a cell edge, where the
    world's collision test (walls as whole cells) leaves it 0.05 m each side; 5 cells touch."""
    free = np.zeros((30, 40), bool)
    free[1:29, 1:19] = True
    free[1:29, 21:39] = True
    top = 15 - door_cells // 2
    free[top:top + door_cells, 19:21] = True
    assert bool(body_fits(free, 2.5)[top:top + door_cells, 19:21].any()) == passes
    occ = OccupancyMap(free=free, resolution_m=0.1, origin_x_m=0.0, origin_y_m=0.0, name="door")
    reach = reachable_free(occ, (0.5, 1.5), connectivity=4, robot_radius_m=0.25)
    assert bool(reach[:, 25:].any()) == passes           # beyond what the body sweeps from the door
