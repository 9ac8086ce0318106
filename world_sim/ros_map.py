"""Ground truth from any ROS `map_server` map (a YAML file naming an image).

The pixel rules follow ROS 1 map_server's image_loader.cpp, because that is what the maps in
the wild were drawn for:
- the channels of a pixel are averaged; in trinary mode an alpha channel is averaged in too,
  in scale and raw mode it is left out (map_server does exactly this);
- `negate` flips the average (`255 - avg`) before anything else;
- trinary / scale: occupancy p = (255 - avg) / 255; free where p < free_thresh;
- raw: the (negated) average *is* the occupancy in percent (0..100; anything above 100 is
  map_server's "unknown"); free where value / 100 < free_thresh, so the YAML's threshold keeps
  its meaning in all three modes.
For a simulator's ground truth every cell that is not free is wall: unknown space in a recorded
map is space no robot has seen, and several real maps are open at their edges.

A palette image is read through its palette (what a person sees), not by its index values.
16-bit images are scaled to 0..255 first.
"""
from __future__ import annotations

import math
import os
from pathlib import Path

import numpy as np
import yaml
from PIL import Image, UnidentifiedImageError
from scipy import ndimage

from world_sim.occupancy_map import OccupancyMap

_REQUIRED = ("image", "resolution", "origin", "negate", "occupied_thresh", "free_thresh")
_MODES = ("trinary", "scale", "raw")
_EIGHT_CONNECTED = np.ones((3, 3), dtype=bool)

# Bounds on what a map file may ask for, checked before anything is allocated. The lower
# resolution bound keeps the robot disc (0.25 m) at most 25 cells across its radius; the cell
# count keeps a mission's per-cell grids (ground truth, walls, clearance, what each robot
# saw, the reachable areas: about BYTES_PER_CELL bytes for one robot) within a few GiB.
RESOLUTION_MIN_M = 0.01
RESOLUTION_MAX_M = 1.0
MAX_CELLS = 64_000_000
BYTES_PER_CELL = 24
MAX_YAML_BYTES = 1 << 20


class MapFormatError(ValueError):
    """A map file that cannot be turned into ground truth; the message names file, line, field."""


def load_ros_map(yaml_path: str | os.PathLike) -> OccupancyMap:
    """Load a map_server YAML + image as an OccupancyMap (row 0 = lowest y)."""
    path = Path(yaml_path)
    where = path.name
    try:
        if path.is_dir():
            raise MapFormatError(f"{path}: cannot read map YAML: it is a folder")
        with open(path, "rb") as f:
            data = f.read(MAX_YAML_BYTES + 1)
        if len(data) > MAX_YAML_BYTES:
            raise MapFormatError(f"{path}: map YAML is longer than {MAX_YAML_BYTES} bytes; a map_server YAML "
                                 "is a few lines")
        text = data.decode("utf-8")
    except FileNotFoundError:
        raise MapFormatError(f"{path}: map YAML file not found") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise MapFormatError(f"{path}: cannot read map YAML: {exc}") from None

    fields = _parse_yaml_fields(text, where)
    resolution_m = _positive_number(fields, "resolution", where)
    if not RESOLUTION_MIN_M <= resolution_m <= RESOLUTION_MAX_M:
        raise MapFormatError(
            f"{where}:{fields['resolution'][1]}: field 'resolution': {resolution_m:g} m per cell is outside "
            f"{RESOLUTION_MIN_M:g}..{RESOLUTION_MAX_M:g} m"
        )
    origin_x_m, origin_y_m = _origin(fields, where)
    negate = _negate(fields, where)
    occupied_thresh = _unit_interval(fields, "occupied_thresh", where)
    free_thresh = _unit_interval(fields, "free_thresh", where)
    if free_thresh >= occupied_thresh:
        line = fields["free_thresh"][1]
        raise MapFormatError(
            f"{where}:{line}: field 'free_thresh': must be below occupied_thresh "
            f"({occupied_thresh:g}), got {free_thresh:g}"
        )
    mode = _mode(fields, where)
    image_path = _image_path(fields, path, where)

    average = _channel_average(image_path, mode, where, fields["image"][1], resolution_m)
    if negate:
        average = 255.0 - average
    if mode == "raw":
        value = np.rint(average)
        free_top_down = (value <= 100.0) & (value / 100.0 < free_thresh)
    else:
        occupancy = (255.0 - average) / 255.0
        free_top_down = occupancy < free_thresh

    return OccupancyMap(
        free=np.ascontiguousarray(np.flipud(free_top_down)),
        resolution_m=resolution_m,
        origin_x_m=origin_x_m,
        origin_y_m=origin_y_m,
        name=path.name,
    )


def reachable_free(
    occ: OccupancyMap, start_xy: tuple[float, float], connectivity: int = 8,
    robot_radius_m: float | None = None,
) -> np.ndarray:
    """Bool grid of the free component (8- or 4-connected) that contains the start point.

    8-connected lets a component leak through pixel-diagonal chinks in drawn walls; the
    areas in the shared maps' README are the 4-connected ones. With robot_radius_m, the answer
    is instead the area a robot body of that radius can sweep from the start: the connected
    set of cells where the disc fits (body_fits), grown back by the disc. Gaps narrower than
    the robot cut the component there; in recorded SLAM maps that drops the fans of free beams
    drawn through chinks in walls into closed courtyards, where no robot can go."""
    if connectivity not in (4, 8):
        raise ValueError(f"connectivity must be 4 or 8, got {connectivity!r}")
    row, col = occ.cell_of(float(start_xy[0]), float(start_xy[1]))
    if not (0 <= row < occ.rows and 0 <= col < occ.cols):
        raise ValueError(
            f"start ({start_xy[0]:.3f}, {start_xy[1]:.3f}) m lies outside map '{occ.name}' "
            f"(x {occ.origin_x_m:g}..{occ.origin_x_m + occ.width_m:g} m, "
            f"y {occ.origin_y_m:g}..{occ.origin_y_m + occ.height_m:g} m)"
        )
    if not occ.free[row, col]:
        raise ValueError(
            f"start ({start_xy[0]:.3f}, {start_xy[1]:.3f}) m is in a wall cell "
            f"(row {row}, col {col}) of map '{occ.name}'"
        )
    structure = _EIGHT_CONNECTED if connectivity == 8 else None
    if robot_radius_m is None:
        labels, _ = ndimage.label(occ.free, structure=structure)
        return labels == labels[row, col]
    r = max(1, int(np.ceil(robot_radius_m / occ.resolution_m)))
    yy, xx = np.mgrid[-r:r + 1, -r:r + 1]
    disc = (xx * xx + yy * yy) <= r * r
    centres = body_fits(occ.free, robot_radius_m / occ.resolution_m)
    if not centres[row, col]:
        raise ValueError(
            f"start ({start_xy[0]:.3f}, {start_xy[1]:.3f}) m of map '{occ.name}' has no room "
            f"for a robot of radius {robot_radius_m} m")
    labels, _ = ndimage.label(centres, structure=structure)
    return ndimage.binary_dilation(labels == labels[row, col], structure=disc) & occ.free


# Where in a cell a body may stand: its centre, the midpoints of its sides, its corners (in
# half cells). A door an even number of cells wide has its middle on a cell edge.
_STANDING_POINTS = [(0, 0), (-1, 0), (1, 0), (0, -1), (0, 1), (-1, -1), (-1, 1), (1, -1), (1, 1)]


def reachable_from_starts(occ, poses, robot_radius_m: float | None = None) -> np.ndarray:
    """The union of the free components reachable from every start pose (x, y, ...): robots
    given starts in separate parts of a map explore all of them. Staging areas lie in one
    component, so for them this is the first start's component. Missions are scored on it."""
    reachable = reachable_free(occ, poses[0][:2], connectivity=4, robot_radius_m=robot_radius_m)
    for x, y, *_ in poses[1:]:
        row, col = occ.cell_of(x, y)
        if not reachable[row, col]:
            reachable |= reachable_free(occ, (x, y), connectivity=4, robot_radius_m=robot_radius_m)
    return reachable


def body_fits(free: np.ndarray, radius_cells: float) -> np.ndarray:
    """Bool grid: free cells with a point (centre, side midpoint or corner) where a disc of
    radius_cells touches no wall cell (walls are whole cells, as the world's collision test
    takes them; the grid's edge counts as wall). A door of 6 cells passes a body 5 cells wide
    through its middle, which lies on a cell edge, so testing cell centres alone would close
    it."""
    padded = np.pad(free, 1, constant_values=False)
    # Distances between centres bound the answer: a cell's points lie within sqrt(2)/2 of its
    # centre, and a wall cell's square within sqrt(2)/2 of the wall's centre.
    d_centre = ndimage.distance_transform_edt(padded)
    sure = padded & (d_centre - math.sqrt(2.0) > radius_cells)
    maybe = padded & ~sure & (d_centre + math.sqrt(2.0) / 2.0 - 0.5 > radius_cells)
    rows, cols = np.nonzero(maybe)
    fits = sure.copy()
    if len(rows):
        reach = int(math.ceil(radius_cells + 1.5))
        best = np.zeros(len(rows), bool)
        for pi, pj in _STANDING_POINTS:
            nearest = np.full(len(rows), np.inf)
            for di in range(-reach, reach + 1):
                for dj in range(-reach, reach + 1):
                    wi, wj = rows + di, cols + dj
                    inside = (wi >= 0) & (wi < padded.shape[0]) & (wj >= 0) & (wj < padded.shape[1])
                    wall = np.ones(len(rows), bool)
                    wall[inside] = ~padded[wi[inside], wj[inside]]
                    gap_i = max(abs(di - 0.5 * pi) - 0.5, 0.0)
                    gap_j = max(abs(dj - 0.5 * pj) - 0.5, 0.0)
                    nearest = np.where(wall, np.minimum(nearest, math.hypot(gap_i, gap_j)), nearest)
            best |= nearest > radius_cells
        fits[rows, cols] = best
    return fits[1:-1, 1:-1]


def reachable_area_m2(
    occ: OccupancyMap, start_xy: tuple[float, float], connectivity: int = 8
) -> float:
    """Area of the free component containing the start, in square metres."""
    cells = np.count_nonzero(reachable_free(occ, start_xy, connectivity))
    return float(cells) * occ.resolution_m ** 2


# ----------------------------------------------------------------------------- YAML fields


def _parse_yaml_fields(text: str, where: str) -> dict[str, tuple[object, int]]:
    """Top-level key -> (python value, 1-based line of the value)."""
    try:
        root = yaml.compose(text, Loader=yaml.SafeLoader)
    except RecursionError:
        raise MapFormatError(f"{where}: malformed YAML: nested too deeply for a map_server YAML") from None
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None) or getattr(exc, "context_mark", None)
        line = f":{mark.line + 1}" if mark is not None else ""
        problem = getattr(exc, "problem", None) or str(exc)
        context, context_mark = getattr(exc, "context", None), getattr(exc, "context_mark", None)
        if context and context_mark is not None and context_mark is not mark:
            problem += f" ({context} started at line {context_mark.line + 1})"
        raise MapFormatError(f"{where}{line}: malformed YAML: {problem}") from None
    if root is None:
        raise MapFormatError(f"{where}: empty map YAML; needs fields {', '.join(_REQUIRED)}")
    if not isinstance(root, yaml.MappingNode):
        raise MapFormatError(
            f"{where}:{root.start_mark.line + 1}: expected a mapping of fields "
            f"({', '.join(_REQUIRED)}), got a {root.id}"
        )
    constructor = yaml.SafeLoader("")
    fields: dict[str, tuple[object, int]] = {}
    for key_node, value_node in root.value:
        line = key_node.start_mark.line + 1
        try:
            key = constructor.construct_object(key_node, deep=True)
            value = constructor.construct_object(value_node, deep=True)
        except RecursionError:
            raise MapFormatError(f"{where}:{line}: malformed YAML value: nested too deeply") from None
        except (yaml.YAMLError, TypeError) as exc:
            raise MapFormatError(f"{where}:{line}: malformed YAML value: {exc}") from None
        if not isinstance(key, str):
            continue  # map_server ignores anything it does not look up
        if key in fields:
            raise MapFormatError(
                f"{where}:{line}: field '{key}': duplicate key (first at line {fields[key][1]})"
            )
        fields[key] = (value, value_node.start_mark.line + 1)
    missing = [name for name in _REQUIRED if name not in fields]
    if missing:
        names = ", ".join(f"'{m}'" for m in missing)
        raise MapFormatError(
            f"{where}:{root.start_mark.line + 1}: missing required field{'s' if len(missing) > 1 else ''} {names}"
        )
    return fields


def _as_number(value: object) -> float | None:
    # yaml-cpp (which map_server uses) reads any scalar that spells a number, quoted or not,
    # and YAML 1.1 leaves `5e-2` a string: accept both, reject booleans and non-finite values.
    if isinstance(value, bool):
        return None
    if isinstance(value, (int, float)):
        number = float(value)
    elif isinstance(value, str):
        try:
            number = float(value.strip())
        except ValueError:
            return None
    else:
        return None
    return number if math.isfinite(number) else None


def _positive_number(fields, name: str, where: str) -> float:
    value, line = fields[name]
    number = _as_number(value)
    if number is None or number <= 0.0:
        raise MapFormatError(f"{where}:{line}: field '{name}': expected a positive number, got {value!r}")
    return number


def _unit_interval(fields, name: str, where: str) -> float:
    value, line = fields[name]
    number = _as_number(value)
    if number is None or not 0.0 <= number <= 1.0:
        raise MapFormatError(
            f"{where}:{line}: field '{name}': expected a number in [0, 1], got {value!r}"
        )
    return number


def _origin(fields, where: str) -> tuple[float, float]:
    value, line = fields["origin"]
    if not isinstance(value, list) or len(value) != 3:
        raise MapFormatError(
            f"{where}:{line}: field 'origin': expected [x, y, yaw] (three numbers), got {value!r}"
        )
    numbers = [_as_number(v) for v in value]
    for label, number, raw in zip(("x", "y", "yaw"), numbers, value):
        if number is None:
            raise MapFormatError(
                f"{where}:{line}: field 'origin': {label} must be a number, got {raw!r}"
            )
    if numbers[2] != 0.0:
        raise MapFormatError(
            f"{where}:{line}: field 'origin': rotated origins are unsupported "
            f"(yaw must be 0, got {numbers[2]:g} rad)"
        )
    return numbers[0], numbers[1]


def _negate(fields, where: str) -> bool:
    value, line = fields["negate"]
    if isinstance(value, bool):
        return value
    if isinstance(value, int) and value in (0, 1):
        return bool(value)
    raise MapFormatError(f"{where}:{line}: field 'negate': expected 0 or 1, got {value!r}")


def _mode(fields, where: str) -> str:
    if "mode" not in fields:
        return "trinary"
    value, line = fields["mode"]
    if not isinstance(value, str) or value.strip().lower() not in _MODES:
        raise MapFormatError(
            f"{where}:{line}: field 'mode': expected one of {', '.join(_MODES)}, got {value!r}"
        )
    return value.strip().lower()


def _image_path(fields, yaml_path: Path, where: str) -> Path:
    value, line = fields["image"]
    if not isinstance(value, str) or not value.strip():
        raise MapFormatError(f"{where}:{line}: field 'image': expected an image file name, got {value!r}")
    image = Path(value.strip())
    if not image.is_absolute():
        image = yaml_path.parent / image
    if not image.is_file():
        raise MapFormatError(f"{where}:{line}: field 'image': image file not found: {image}")
    return image


# ----------------------------------------------------------------------------- image


def _channel_average(image_path: Path, mode: str, where: str, line: int, resolution_m: float) -> np.ndarray:
    """Per-pixel channel mean (0..255 float, top row first) with map_server's alpha rule.
    The image's size is checked (from its header) before its pixels are decoded."""
    try:
        with Image.open(image_path) as img:
            _check_size(img.size, image_path, where, line, resolution_m)
            img.load()
            pixels = _pixels_0_255(img)
    except MapFormatError:
        raise
    except (UnidentifiedImageError, OSError, SyntaxError, ValueError, Image.DecompressionBombError) as exc:
        raise MapFormatError(
            f"{where}:{line}: field 'image': cannot decode image {image_path}: {exc}"
        ) from None
    if pixels.ndim != 3 or pixels.shape[0] == 0 or pixels.shape[1] == 0:
        raise MapFormatError(f"{where}:{line}: field 'image': image {image_path} has no pixels")
    channels, has_alpha = pixels.shape[2], pixels.shape[2] in (2, 4)
    if has_alpha and channels == 2:
        # map_server's loader sees grey+alpha as RGBA with three equal colour channels
        grey, alpha = pixels[..., 0:1], pixels[..., 1:2]
        pixels = np.concatenate([grey, grey, grey, alpha], axis=2)
    if has_alpha and mode != "trinary":
        pixels = pixels[..., :-1]
    return pixels.mean(axis=2)


def _check_size(size: tuple[int, int], image_path: Path, where: str, line: int, resolution_m: float) -> None:
    cols, rows = size
    cells = cols * rows
    if cells > MAX_CELLS:
        raise MapFormatError(
            f"{where}:{line}: field 'image': {image_path} is {cols} x {rows} pixels ({cols * resolution_m:g} x "
            f"{rows * resolution_m:g} m at the map's resolution), {cells} cells: a mission would need about "
            f"{cells * BYTES_PER_CELL / 2**30:.1f} GiB for one robot; at most {MAX_CELLS} cells"
        )


def _pixels_0_255(img: Image.Image) -> np.ndarray:
    """(rows, cols, channels) float64 in 0..255 for any Pillow mode."""
    if img.mode == "P":
        img = img.convert("RGBA" if "transparency" in img.info else "RGB")
    elif img.mode == "PA":
        img = img.convert("RGBA")
    elif img.mode in ("1", "CMYK", "YCbCr", "LAB", "HSV"):
        img = img.convert("L" if img.mode == "1" else "RGB")
    elif img.mode == "La":
        img = img.convert("LA")
    elif img.mode == "RGBa":
        img = img.convert("RGBA")
    array = np.asarray(img)
    if img.mode.startswith("I;16") or array.dtype == np.uint16:
        array = array.astype(np.float64) / 257.0
    elif img.mode == "I":
        # Pillow widens 16-bit sources (PGM maxval > 255, 16-bit PNG) to "I", scaled to 0..65535
        array = array.astype(np.float64) / 257.0
    elif img.mode == "F":
        array = array.astype(np.float64)
        if array.size and np.nanmax(array) <= 1.0:
            array = array * 255.0
    else:
        array = array.astype(np.float64)
    if array.ndim == 2:
        array = array[:, :, None]
    return np.clip(array, 0.0, 255.0)
