"""One string names a ground-truth map: a ROS map YAML path, or a seeded generated world.

    depot.yaml / /abs/path/intel.yaml     ROS map_server map, start = default_start(map)
    cave:SEED  /  cave:SEED:WxH           generated cave, W x H metres (default 100x100)
    tunnel:SEED / tunnel:SEED:WxH         generated mine tunnels
    office:SEED / office:SEED:WxH         generated office floor: rooms behind doors 0.6-1.0 m
                                          clear, furniture (default 40x30, at most 200 m a side)

Also the start-pose helpers every mission needs: a deterministic default start and a set of
staging poses around it for a team.
"""
from __future__ import annotations

import heapq
import math
import re
from pathlib import Path

import numpy as np
from scipy import ndimage

from world_sim.occupancy_map import OccupancyMap

Pose = tuple[float, float, float]  # (x_m, y_m, yaw_rad)

DEFAULT_SIZE_M = (100.0, 100.0)
MAX_SIDE_M = 2000.0
_GENERATED_KINDS = ("cave", "tunnel", "office")
_EIGHT_CONNECTED = np.ones((3, 3), dtype=bool)
_SPEC_HELP = (
    "accepted: a path to a ROS map .yaml, or cave:SEED, tunnel:SEED, office:SEED, "
    "cave:SEED:WxH, tunnel:SEED:WxH, office:SEED:WxH (SEED a non-negative integer, W and H in metres, "
    "e.g. cave:3:200x150)"
)
_HEADINGS = 16
_HEADING_LOOK_M = 20.0


class MapSpecError(ValueError):
    """A map spec string that names no map; the message says what is wrong and what is accepted."""


SEED_MAX = 2**32 - 1


def resolve_map(spec: str) -> tuple[OccupancyMap, Pose, str]:
    """(ground truth, start pose, label for reports) for a map spec string."""
    text, kind = _spec_kind(spec)
    if kind in _GENERATED_KINDS:
        return _resolve_generated(text, kind)
    from world_sim.ros_map import load_ros_map

    occ = load_ros_map(text)
    return occ, default_start(occ), Path(text).name


def check_map_spec(spec: str) -> None:
    """MapSpecError or MapFormatError (file, line, field) unless `spec` names a map: a ROS map
    is loaded (its checks need the image), a generated one only parsed, not generated."""
    text, kind = _spec_kind(spec)
    if kind in _GENERATED_KINDS:
        _parse_generated(text, kind)
    else:
        from world_sim.ros_map import load_ros_map

        load_ros_map(text)


def _spec_kind(spec: str) -> tuple[str, str]:
    """(stripped spec, one of _GENERATED_KINDS or 'yaml')."""
    if not isinstance(spec, str) or not spec.strip():
        raise MapSpecError(f"empty map spec; {_SPEC_HELP}")
    text = spec.strip()
    kind = text.split(":", 1)[0].lower()
    if kind in _GENERATED_KINDS and ":" in text:
        return text, kind
    if text.lower().endswith((".yaml", ".yml")):
        return text, "yaml"
    raise MapSpecError(f"unrecognised map spec {spec!r}; {_SPEC_HELP}")


def _generator(kind: str):
    """(generate(seed, width_m=, height_m=) -> (map, start), default (width_m, height_m), largest
    side in metres) of a generated kind. Imported here: the generators import this module."""
    from world_sim import office, procgen

    if kind == "office":
        return office.generate_office, office.DEFAULT_SIZE_M, office.MAX_SIDE_M
    generate = procgen.generate_cave if kind == "cave" else procgen.generate_tunnel
    return generate, DEFAULT_SIZE_M, MAX_SIDE_M


def _parse_generated(text: str, kind: str) -> tuple[int, float, float]:
    """(seed, width_m, height_m) of a cave:/tunnel:/office: spec, checked."""
    from world_sim import procgen

    _, default_size_m, max_side_m = _generator(kind)
    parts = text.split(":")
    if len(parts) not in (2, 3):
        raise MapSpecError(f"map spec {text!r} has {len(parts) - 1} ':' separators; {_SPEC_HELP}")
    seed_text = parts[1].strip()
    if not re.fullmatch(r"\d+", seed_text):
        raise MapSpecError(f"map spec {text!r}: seed {seed_text!r} is not a non-negative integer; {_SPEC_HELP}")
    if len(seed_text) > 10 or int(seed_text) > SEED_MAX:
        raise MapSpecError(f"map spec {text!r}: seed {seed_text} is out of range 0..{SEED_MAX}")
    seed = int(seed_text)
    width_m, height_m = default_size_m
    if len(parts) == 3:
        match = re.fullmatch(r"\s*(\d{1,6}(?:\.\d{1,6})?)\s*[xX]\s*(\d{1,6}(?:\.\d{1,6})?)\s*", parts[2])
        if match is None:
            raise MapSpecError(f"map spec {text!r}: size {parts[2]!r} is not WxH in metres; {_SPEC_HELP}")
        width_m, height_m = float(match.group(1)), float(match.group(2))
        lo = procgen.MIN_SIDE_M
        for name, value in (("width", width_m), ("height", height_m)):
            if not lo <= value <= max_side_m:
                raise MapSpecError(
                    f"map spec {text!r}: {name} {value:g} m is outside {lo:g}..{max_side_m:g} m"
                )
    return seed, width_m, height_m


def _resolve_generated(text: str, kind: str) -> tuple[OccupancyMap, Pose, str]:
    seed, width_m, height_m = _parse_generated(text, kind)
    generate, _, _ = _generator(kind)
    occ, start = generate(seed, width_m=width_m, height_m=height_m)
    label = f"{kind}:{seed}:{width_m:g}x{height_m:g}"
    return occ, start, label


# ----------------------------------------------------------------------------- start poses


def clearance_field_m(free: np.ndarray, resolution_m: float) -> np.ndarray:
    """Distance (m) from each free cell's centre to the nearest wall face; 0 on walls.

    Outside the grid counts as wall, so a map open at its edge never yields a start that
    looks roomy only because the world ends there."""
    padded = np.pad(free, 1, constant_values=False)
    centre_to_centre = ndimage.distance_transform_edt(padded)[1:-1, 1:-1]
    return np.where(free, (centre_to_centre - 0.5) * resolution_m, 0.0)


def open_heading_rad(free: np.ndarray, row: int, col: int, resolution_m: float) -> float:
    """Yaw of the longest free straight run from a cell (16 headings, first one wins ties)."""
    steps = max(1, int(round(_HEADING_LOOK_M / resolution_m)))
    distance = np.arange(1, steps + 1, dtype=np.float64)
    best_k, best_run = 0, -1
    for k in range(_HEADINGS):
        angle = 2.0 * math.pi * k / _HEADINGS
        rows = np.floor(row + 0.5 + distance * math.sin(angle)).astype(np.int64)
        cols = np.floor(col + 0.5 + distance * math.cos(angle)).astype(np.int64)
        inside = (rows >= 0) & (rows < free.shape[0]) & (cols >= 0) & (cols < free.shape[1])
        ok = inside.copy()
        ok[inside] = free[rows[inside], cols[inside]]
        run = steps if ok.all() else int(np.argmin(ok))
        if run > best_run:
            best_k, best_run = k, run
    return 2.0 * math.pi * best_k / _HEADINGS


def default_start(occ: OccupancyMap) -> Pose:
    """The most open cell of the largest free component (first in row-major order on ties),
    facing its longest free straight run."""
    labels, count = ndimage.label(occ.free, structure=_EIGHT_CONNECTED)
    if count == 0:
        raise ValueError(f"map '{occ.name}' has no free cell to start in")
    sizes = np.bincount(labels.ravel())
    sizes[0] = 0
    largest = int(np.argmax(sizes))
    clearance = clearance_field_m(occ.free, occ.resolution_m)
    clearance[labels != largest] = -1.0
    row, col = np.unravel_index(int(np.argmax(clearance)), clearance.shape)
    x_m, y_m = occ.center_of(int(row), int(col))
    return (x_m, y_m, open_heading_rad(occ.free, int(row), int(col), occ.resolution_m))


def staging_poses(
    occ: OccupancyMap, start: Pose, n: int, spacing_m: float = 1.0, clearance_m: float = 0.5
) -> list[Pose]:
    """n poses around `start`, pairwise at least spacing_m apart, each on a cell at least
    clearance_m from any wall, all in one region a robot of that clearance can drive through.

    Pose 0 is the start itself when it has the clearance. The rest are taken nearest first by
    driving distance (8-connected steps through roomy cells), so a team shares one staging
    area instead of being spread through walls. All poses face the start's yaw. The search
    stays within staging_reach_m(n, spacing_m) of driving distance (a staging area, not the
    whole map), so it costs the same on a 25 M-cell map as on a small one."""
    clearance_m_min = float(clearance_m)
    if n < 0:
        raise ValueError(f"n must be >= 0, got {n}")
    if not spacing_m > 0.0 or not clearance_m_min >= 0.0:
        raise ValueError(f"spacing_m must be > 0 and clearance_m >= 0, got {spacing_m}, {clearance_m_min}")
    if n == 0:
        return []
    x0, y0, yaw = float(start[0]), float(start[1]), float(start[2])
    row0, col0 = occ.cell_of(x0, y0)
    if not (0 <= row0 < occ.rows and 0 <= col0 < occ.cols) or not occ.free[row0, col0]:
        raise ValueError(f"start ({x0:.3f}, {y0:.3f}) m is not on a free cell of map '{occ.name}'")
    res = occ.resolution_m
    reach_m = staging_reach_m(n, spacing_m)
    # Work in a window: cells farther than reach_m are never visited, and treating the window
    # edge as wall only changes the clearance of cells farther than that.
    half = int(math.ceil((reach_m + clearance_m_min) / res)) + 2
    r_lo, c_lo = max(row0 - half, 0), max(col0 - half, 0)
    window = occ.free[r_lo:row0 + half + 1, c_lo:col0 + half + 1]
    roomy = clearance_field_m(window, res) >= clearance_m_min
    seed_cell = _nearest_roomy_cell(window, roomy, row0 - r_lo, col0 - c_lo)
    if seed_cell is None:
        raise ValueError(
            f"no cell with {clearance_m_min:g} m clearance is reachable within {reach_m:.1f} m "
            f"of the start ({x0:.3f}, {y0:.3f}) m on map '{occ.name}'"
        )
    chosen_rc: list[tuple[float, float]] = []  # window cells, for the spacing test
    poses: list[Pose] = []
    spacing_cells2 = (spacing_m / res) ** 2
    if seed_cell == (row0 - r_lo, col0 - c_lo):
        chosen_rc.append(((y0 - occ.origin_y_m) / res - 0.5 - r_lo, (x0 - occ.origin_x_m) / res - 0.5 - c_lo))
        poses.append((x0, y0, yaw))
    # Dijkstra over roomy cells, octile step costs; ties broken by (row, col) for determinism
    reach_cells = reach_m / res
    seen = np.zeros(roomy.shape, dtype=bool)
    heap = [(0.0, seed_cell[0], seed_cell[1])]
    best = {seed_cell: 0.0}
    neighbours = [(-1, -1), (-1, 0), (-1, 1), (0, -1), (0, 1), (1, -1), (1, 0), (1, 1)]
    while heap and len(poses) < n:
        dist, r, c = heapq.heappop(heap)
        if seen[r, c]:
            continue
        if dist > reach_cells:
            break
        seen[r, c] = True
        if all((r - cr) ** 2 + (c - cc) ** 2 >= spacing_cells2 - 1e-9 for cr, cc in chosen_rc):
            chosen_rc.append((float(r), float(c)))
            poses.append((*occ.center_of(r + r_lo, c + c_lo), yaw))
        for dr, dc in neighbours:
            rr, cc = r + dr, c + dc
            if 0 <= rr < roomy.shape[0] and 0 <= cc < roomy.shape[1] and roomy[rr, cc] and not seen[rr, cc]:
                nd = dist + (math.sqrt(2.0) if dr and dc else 1.0)
                if nd < best.get((rr, cc), math.inf):
                    best[(rr, cc)] = nd
                    heapq.heappush(heap, (nd, rr, cc))
    if len(poses) < n:
        raise ValueError(
            f"only {len(poses)} of {n} staging poses fit {spacing_m:g} m apart with "
            f"{clearance_m_min:g} m clearance within {reach_m:.1f} m of the start on map '{occ.name}'"
        )
    return poses


def staging_reach_m(n: int, spacing_m: float) -> float:
    """Driving distance from the start within which staging_poses looks: room for n poses
    even along a single corridor, plus slack for corners."""
    return spacing_m * (n + 5.0)


def _nearest_roomy_cell(free: np.ndarray, roomy: np.ndarray, row0: int, col0: int):
    """The roomy cell nearest the start within the start's free component, or None."""
    if roomy[row0, col0]:
        return (row0, col0)
    labels, _ = ndimage.label(free, structure=_EIGHT_CONNECTED)
    candidates = roomy & (labels == labels[row0, col0])
    if not candidates.any():
        return None
    rows, cols = np.nonzero(candidates)
    d2 = (rows - row0) ** 2 + (cols - col0) ** 2
    i = int(np.lexsort((cols, rows, d2))[0])
    return (int(rows[i]), int(cols[i]))


SPREAD_STEP_M = 0.2        # spread_poses measures driving distances on a lattice this coarse


def spread_poses(occ: OccupancyMap, start: Pose, n: int, min_sep_m: float, max_sep_m: float = 0.0,
                 seed: int = 0, clearance_m: float = 0.5, body_m: float = 0.25) -> list[Pose]:
    """n start poses spread over the map (issue 25 item 1): each on a cell at least
    clearance_m from any wall, all in the region a body of radius body_m can drive to from
    `start`,
    pairwise at least min_sep_m of driving distance apart and, with max_sep_m > 0, each but
    the first at most max_sep_m of driving from the nearest one chosen before it (so a team
    stays within reach of itself). Positions and yaws (uniform in [-pi, pi)) are drawn from
    their own random stream of `seed`: the same seed, the same poses.

    Driving distances are 8-connected shortest paths over roomy cells, on a lattice of
    SPREAD_STEP_M (a lattice cell is roomy if any map cell in it is: that keeps every
    corridor connected, and errs by at most a lattice cell per step). Raises ValueError
    naming what does not fit."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import dijkstra

    if n < 1:
        raise ValueError(f"n must be >= 1, got {n}")
    if not (min_sep_m >= 0.0 and max_sep_m >= 0.0) or (max_sep_m and max_sep_m < min_sep_m):
        raise ValueError(f"need 0 <= min_sep_m <= max_sep_m (or max_sep_m 0: no bound), got {min_sep_m}, {max_sep_m}")
    res = occ.resolution_m
    clearance = clearance_field_m(occ.free, res)
    fits = clearance >= min(body_m, clearance_m)
    r0, c0 = occ.cell_of(float(start[0]), float(start[1]))
    seed_cell = _nearest_roomy_cell(occ.free, fits, r0, c0) if 0 <= r0 < occ.rows and 0 <= c0 < occ.cols \
        and occ.free[r0, c0] else None
    if seed_cell is None:
        raise ValueError(f"no cell with {body_m:g} m clearance is reachable from the start "
                         f"({start[0]:.3f}, {start[1]:.3f}) m on map '{occ.name}'")
    labels, _ = ndimage.label(fits, structure=_EIGHT_CONNECTED)
    region = labels == labels[seed_cell]
    roomy = region & (clearance >= clearance_m)
    f = max(1, int(round(SPREAD_STEP_M / res)))
    rows, cols = -(-occ.rows // f), -(-occ.cols // f)
    padded = np.zeros((rows * f, cols * f), bool)
    padded[:occ.rows, :occ.cols] = region
    coarse = padded.reshape(rows, f, cols, f).any(axis=(1, 3))
    padded[:occ.rows, :occ.cols] = roomy
    standable = padded.reshape(rows, f, cols, f).any(axis=(1, 3))
    index = -np.ones(coarse.shape, np.int64)
    cells = np.argwhere(coarse)
    index[cells[:, 0], cells[:, 1]] = np.arange(len(cells))
    src, dst, w = [], [], []
    for dr, dc in ((0, 1), (1, 0), (1, 1), (1, -1)):
        a = cells
        b = cells + (dr, dc)
        ok = (b[:, 0] >= 0) & (b[:, 0] < rows) & (b[:, 1] >= 0) & (b[:, 1] < cols)
        a, b = a[ok], b[ok]
        ok = coarse[b[:, 0], b[:, 1]]
        a, b = a[ok], b[ok]
        src.append(index[a[:, 0], a[:, 1]])
        dst.append(index[b[:, 0], b[:, 1]])
        w.append(np.full(len(a), math.hypot(dr, dc) * f * res))
    src, dst, w = np.concatenate(src), np.concatenate(dst), np.concatenate(w)
    graph = coo_matrix((np.concatenate([w, w]), (np.concatenate([src, dst]), np.concatenate([dst, src]))),
                       shape=(len(cells), len(cells))).tocsr()
    rng = np.random.default_rng([int(seed), 0x53505244])      # "SPRD": a stream of its own
    can_stand = standable[cells[:, 0], cells[:, 1]]
    if not can_stand.any():
        raise ValueError(f"no cell with {clearance_m:g} m clearance is reachable from the start on map '{occ.name}'")
    first = np.flatnonzero(can_stand)
    chosen: list[int] = [int(first[rng.integers(len(first))])]
    while len(chosen) < n:
        dist = dijkstra(graph, directed=False, indices=chosen, min_only=True)
        ok = can_stand & np.isfinite(dist) & (dist >= min_sep_m)
        if max_sep_m:
            ok &= dist <= max_sep_m
        pool = np.flatnonzero(ok)
        if not len(pool):
            raise ValueError(f"only {len(chosen)} of {n} start poses fit {min_sep_m:g} m of driving apart"
                             + (f" and within {max_sep_m:g} m of another" if max_sep_m else "")
                             + f" on map '{occ.name}'")
        chosen.append(int(pool[rng.integers(len(pool))]))
    poses: list[Pose] = []
    for k in chosen:
        br, bc = cells[k]
        block = roomy[br * f:(br + 1) * f, bc * f:(bc + 1) * f]
        rr, cc = np.nonzero(block)
        mid = (f - 1) / 2.0
        m = int(np.lexsort((cc, rr, (rr - mid) ** 2 + (cc - mid) ** 2))[0])
        x, y = occ.center_of(br * f + int(rr[m]), bc * f + int(cc[m]))
        poses.append((float(x), float(y), float(rng.uniform(-math.pi, math.pi))))
    return poses
