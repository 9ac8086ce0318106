"""Seeded generated office floors: corridors with rooms on both sides, narrow doors, clutter.

A floor is laid out directly in cells, not through a smooth field as caves and tunnels are,
because what it tests is exact: a door of NARROW_DOOR_M clear is that many free cells between
its jambs, and a gap between two pieces of furniture is the number of cells it was placed at.
From the outside in:
- the building is a stack of bands along y, each a room row, a corridor and a room row; the
  room rows of neighbouring bands stand back to back, and cross corridors join the corridors;
- each room row is cut along x into rooms 3 to 8 m a side; walls are one or two cells thick;
- every room has a door to its corridor, except a few that are entered only through the room
  next door; some rooms have a second door (to the corridor, a cross corridor or a neighbour);
- the start room has one door, of exactly the narrowest width, so a planner that keeps more
  than the body's clearance from walls never leaves it;
- rooms are furnished with desks and cabinets against the walls, tables, chairs and pillars in
  the open, some of them at a gap only just wide enough for the body; a piece is kept only if
  the room stays one piece for the body.

"The body gets through" is judged with the body's centre allowed between cell centres
(body_lattice_factor): on whole 0.1 m cells no cell centre lies in the middle of a 0.6 m door,
and a disc test on cell centres calls it shut.

Every random number comes from world_sim.seeding.stream(seed, "procgen.office"), so a seed
names one map bit for bit.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy import ndimage

from world_sim.map_spec import clearance_field_m, open_heading_rad
from world_sim.occupancy_map import OccupancyMap
from world_sim.procgen import _check_size
from world_sim.ros_map import reachable_free
from world_sim.seeding import stream

Pose = tuple[float, float, float]

DEFAULT_SIZE_M = (40.0, 30.0)
# A building floor, not a city: furnishing checks the body still gets round every piece of
# furniture, about a second per 1000 m2 of floor at 0.1 m, so 500 m a side would take minutes.
MAX_SIDE_M = 200.0
# The simulated robot's body (world_sim.world.WorldParams.robot_radius_m; a test keeps them equal).
BODY_RADIUS_M = 0.25
# The narrowest door: the body's diameter and 5 cm to spare on either side.
NARROW_DOOR_M = 2.0 * BODY_RADIUS_M + 0.1
WIDE_DOOR_M = 1.0
CORRIDOR_WIDTH_M = (1.2, 2.0)
ROOM_SIDE_M = (3.0, 8.0)
WALL_CELLS = (1, 2)
OUTER_WALL_CELLS = 2
CROSS_CORRIDOR_EVERY_M = 30.0  # one cross corridor per this much building width
DOOR_JAMB_M = 0.3   # wall kept between a door and the corner of its room
DOOR_APRON_M = 1.0  # depth kept free of furniture in front of a door, on both sides
SHARE_INNER_ROOMS = 0.12     # of the rooms, entered only through the room next door
SHARE_TWO_DOOR_ROOMS = 0.25  # of the rooms, with a second door
PLACEMENT_TRIES = 10

_EIGHT_CONNECTED = np.ones((3, 3), dtype=bool)
_SIDES = ("south", "north", "west", "east")


@dataclass(frozen=True)
class CellRect:
    """Cells [row0, row1) x [col0, col1) of the map grid (row 0 the lowest y)."""

    row0: int
    row1: int
    col0: int
    col1: int

    @property
    def index(self) -> tuple[slice, slice]:
        return slice(self.row0, self.row1), slice(self.col0, self.col1)

    @property
    def height_cells(self) -> int:
        return self.row1 - self.row0

    @property
    def width_cells(self) -> int:
        return self.col1 - self.col0

    def clipped_to(self, other: CellRect) -> CellRect | None:
        """The overlap with `other`, or None when they do not overlap."""
        r0, r1 = max(self.row0, other.row0), min(self.row1, other.row1)
        c0, c1 = max(self.col0, other.col0), min(self.col1, other.col1)
        return CellRect(r0, r1, c0, c1) if r0 < r1 and c0 < c1 else None


@dataclass(frozen=True)
class Beyond:
    """What lies across one wall of a room that a door may go through."""

    kind: str         # "corridor" or "room"
    room: int         # the room's index, -1 for a corridor
    wall_cells: int   # thickness of the wall between


@dataclass
class Room:
    interior: CellRect
    beyond: dict[str, Beyond]  # side ("south", "north", "west", "east") -> what a door there opens on


@dataclass(frozen=True)
class Door:
    opening: CellRect   # the free cells through the wall, wall thickness deep
    clear_cells: int    # free cells between the jambs, along the wall
    side: str           # the wall of `room` it is in
    room: int
    other_room: int     # the room on the far side, -1 for a corridor


@dataclass(frozen=True)
class Squeeze:
    """A gap between two pieces of furniture only just wider than the body."""

    gap: CellRect       # the free cells between the two faces
    gap_cells: int      # how far apart the faces are
    faces_apart_in_y: bool  # True: one piece above the other (the gap is gap_cells rows high)


@dataclass
class OfficeFloor:
    occ: OccupancyMap
    start: Pose
    rooms: list[Room]
    corridors: list[CellRect]
    doors: list[Door]
    squeezes: list[Squeeze]
    start_room: int

    def doors_of(self, room: int) -> list[Door]:
        return [d for d in self.doors if room in (d.room, d.other_room)]


def generate_office(
    seed: int, width_m: float = DEFAULT_SIZE_M[0], height_m: float = DEFAULT_SIZE_M[1],
    resolution_m: float = 0.1,
) -> tuple[OccupancyMap, Pose]:
    """An office floor: corridors, rooms behind doors from 0.6 to 1.0 m clear, furniture."""
    floor = build_office(seed, width_m, height_m, resolution_m)
    return floor.occ, floor.start


def build_office(
    seed: int, width_m: float = DEFAULT_SIZE_M[0], height_m: float = DEFAULT_SIZE_M[1],
    resolution_m: float = 0.1,
) -> OfficeFloor:
    """generate_office's map with its layout: rooms, corridors, doors and narrow gaps.

    Sizes are whole cells: at 0.1 m exactly as the constants say; at other resolutions clear
    widths (doors, gaps) round up, so the body still fits, and the rest to the nearest cell."""
    _check_office_size(width_m, height_m, resolution_m)
    rng = stream(seed, "procgen.office")
    rows = int(round(height_m / resolution_m))
    cols = int(round(width_m / resolution_m))
    strips = _stack_strips(rng, rows, resolution_m)
    runs = [CellRect(s.row0, s.row1, OUTER_WALL_CELLS, cols - OUTER_WALL_CELLS)
            for s in strips if s.kind == "corridor"]
    crossings = _cross_corridors(rng, runs, resolution_m)
    corridors = runs + crossings
    rooms = _rooms(rng, strips, crossings, cols, resolution_m)
    if len(rooms) < 2:
        raise RuntimeError(f"office:{seed}: only {len(rooms)} room fits (generator bug)")
    start_room = _pick_start_room(rng, rooms, resolution_m)
    doors = _place_doors(rng, rooms, _openings(rng, rooms, start_room, resolution_m), resolution_m)
    free = _carve(rows, cols, corridors + [room.interior for room in rooms] + [door.opening for door in doors])
    aprons = _door_aprons(rooms, doors, resolution_m)
    squeezes = [squeeze for index, room in enumerate(rooms)
                for squeeze in _furnish_room(rng, free, room, aprons[index], resolution_m,
                                             staging=(index == start_room))]

    start_rc = _start_cell(free, rooms[start_room], resolution_m)
    _seal_pockets(free, start_rc)
    occ = OccupancyMap(free=free, resolution_m=float(resolution_m), origin_x_m=0.0, origin_y_m=0.0,
                       name=f"office:{seed}")
    x_m, y_m = occ.center_of(*start_rc)
    start = (x_m, y_m, open_heading_rad(free, start_rc[0], start_rc[1], resolution_m))
    floor = OfficeFloor(occ=occ, start=start, rooms=rooms, corridors=corridors, doors=doors,
                        squeezes=squeezes, start_room=start_room)
    _check_rooms_reachable(floor)
    return floor


def _check_office_size(width_m: float, height_m: float, resolution_m: float) -> None:
    """ValueError unless the floor is MIN_SIDE_M..MAX_SIDE_M a side at a resolution procgen takes."""
    _check_size(width_m, height_m, resolution_m)
    for name, value in (("width_m", width_m), ("height_m", height_m)):
        if value > MAX_SIDE_M:
            raise ValueError(f"{name} of an office floor must be at most {MAX_SIDE_M:g} m, got {value!r}")


def _carve(rows: int, cols: int, rects: list[CellRect]) -> np.ndarray:
    """A solid grid with the rectangles made free."""
    free = np.zeros((rows, cols), dtype=bool)
    for rect in rects:
        free[rect.index] = True
    return free


# ----------------------------------------------------------------------------- sizes


def _cells(length_m: float, resolution_m: float) -> int:
    """The nearest whole number of cells, at least one: for sizes that need only be about right."""
    return max(1, int(round(length_m / resolution_m)))


def _clear_cells(length_m: float, resolution_m: float) -> int:
    """The fewest whole cells at least length_m across, so an opening is never narrower than
    asked (the epsilon keeps 0.6 / 0.1 = 5.999... at 6)."""
    return int(math.ceil(length_m / resolution_m - 1e-9))


def _split_length(rng: np.random.Generator, total: int, n: int, lo: int, hi: int) -> list[int]:
    """n sizes in lo..hi, shared out at random, summing to min(total, n * hi) (total >= n * lo)."""
    if total < n * lo:
        raise ValueError(f"{n} sizes of at least {lo} cannot share {total} (generator bug)")
    target = min(total, n * hi)
    extra = target - n * lo
    sizes = np.full(n, lo, dtype=np.int64)
    share = np.minimum(np.floor(rng.dirichlet(np.ones(n)) * extra).astype(np.int64), hi - lo)
    sizes += share
    left = int(target - sizes.sum())
    while left > 0:  # the rounding's few cells, one each to sizes with room left
        open_ = np.nonzero(sizes < hi)[0]
        for i in rng.permutation(open_)[:left]:
            sizes[i] += 1
            left -= 1
    return [int(s) for s in sizes]


# ----------------------------------------------------------------------------- layout


@dataclass(frozen=True)
class _Strip:
    kind: str   # "rooms" or "corridor"
    row0: int
    row1: int


def _stack_strips(rng: np.random.Generator, rows: int, resolution_m: float) -> list[_Strip]:
    """The building's strips from south to north, with walls between: room row, corridor, room
    row, and again for each further band (its first room row back to back with the last one).

    As many bands as fit at a typical 5 m room depth; what the room rows cannot take within
    their 8 m is left as solid wall split between the two ends."""
    room_lo, room_hi = (_cells(m, resolution_m) for m in ROOM_SIDE_M)
    corridor_lo, corridor_hi = (_cells(m, resolution_m) for m in CORRIDOR_WIDTH_M)
    span = rows - 2 * OUTER_WALL_CELLS
    typical_band = 2 * _cells(5.0, resolution_m) + _cells(1.6, resolution_m) + 3 * WALL_CELLS[1]
    bands = max(1, span // typical_band)
    while True:
        walls = [int(rng.integers(WALL_CELLS[0], WALL_CELLS[1] + 1)) for _ in range(3 * bands - 1)]
        corridors = [int(rng.integers(corridor_lo, corridor_hi + 1)) for _ in range(bands)]
        room_budget = span - sum(walls) - sum(corridors)
        if room_budget >= 2 * bands * room_lo or bands == 1:
            break
        bands -= 1
    depths = _split_length(rng, room_budget, 2 * bands, room_lo, room_hi)
    row = OUTER_WALL_CELLS + (room_budget - sum(depths)) // 2
    strips: list[_Strip] = []
    for band in range(bands):
        for kind, size in (("rooms", depths[2 * band]), ("corridor", corridors[band]),
                           ("rooms", depths[2 * band + 1])):
            if strips:
                row += walls[len(strips) - 1]
            strips.append(_Strip(kind, row, row + size))
            row += size
    return strips


def _cross_corridors(rng: np.random.Generator, runs: list[CellRect], resolution_m: float) -> list[CellRect]:
    """Corridors across the building that join the ones along it (`runs`, south to north),
    spread along x and running from the first to the last through the room rows between."""
    if len(runs) < 2:
        return []
    col0, col1 = runs[0].col0, runs[0].col1
    corridor_lo, corridor_hi = (_cells(m, resolution_m) for m in CORRIDOR_WIDTH_M)
    count = max(1, int(round((col1 - col0) * resolution_m / CROSS_CORRIDOR_EVERY_M)))
    section = (col1 - col0) / (count + 1)
    crossings = []
    for i in range(count):
        width = int(rng.integers(corridor_lo, corridor_hi + 1))
        centre = col0 + section * (i + 1) + rng.uniform(-section / 6.0, section / 6.0)
        c0 = int(round(centre - width / 2.0))
        crossings.append(CellRect(runs[0].row0, runs[-1].row1, c0, c0 + width))
    return crossings


def _rooms(rng: np.random.Generator, strips: list[_Strip], crossings: list[CellRect], cols: int,
           resolution_m: float) -> list[Room]:
    """Each room row cut along x into rooms (where cross corridors cut it, in stretches between
    them), with what lies beyond each wall a door may pierce."""
    rooms: list[Room] = []
    for i, strip in enumerate(strips):
        if strip.kind != "rooms":
            continue
        faces_north = i + 1 < len(strips) and strips[i + 1].kind == "corridor"
        corridor = strips[i + 1] if faces_north else strips[i - 1]
        corridor_beyond = ("north", Beyond("corridor", -1, corridor.row0 - strip.row1)) if faces_north \
            else ("south", Beyond("corridor", -1, strip.row0 - corridor.row1))
        crossed = [c for c in crossings if c.row0 < strip.row0 and strip.row1 < c.row1]
        for lo, hi, west_wall, east_wall in _row_segments(rng, cols, crossed):
            first = len(rooms)
            for c0, c1 in _partition_segment(rng, lo, hi, resolution_m):
                rooms.append(Room(CellRect(strip.row0, strip.row1, c0, c1), dict([corridor_beyond])))
            _link_neighbours(rooms, first, west_wall, east_wall)
    return rooms


def _row_segments(rng: np.random.Generator, cols: int, crossings: list[CellRect]):
    """(col0, col1, wall to a cross corridor at the west end or 0, same at the east end) of the
    stretches of a room row between the outer walls and the cross corridors that cut it."""
    bounds = [(None, OUTER_WALL_CELLS)]
    for c in sorted(crossings, key=lambda r: r.col0):
        bounds.append((c.col0, c.col1))
    bounds.append((cols - OUTER_WALL_CELLS, None))
    segments = []
    west_wall = 0
    for (_, prev_end), (next_start, next_end) in zip(bounds, bounds[1:]):
        east_wall = int(rng.integers(WALL_CELLS[0], WALL_CELLS[1] + 1)) if next_end is not None else 0
        lo = prev_end + west_wall
        hi = next_start - east_wall
        segments.append((lo, hi, west_wall, east_wall))
        west_wall = int(rng.integers(WALL_CELLS[0], WALL_CELLS[1] + 1))
    return segments


def _partition_segment(rng: np.random.Generator, lo: int, hi: int, resolution_m: float) -> list[tuple[int, int]]:
    """[col0, col1) of the rooms a stretch of room row is cut into, 3 to 8 m wide with walls of
    one or two cells between; a stretch too short for one room stays solid (a shaft or closet)."""
    room_lo, room_hi = (_cells(m, resolution_m) for m in ROOM_SIDE_M)
    length = hi - lo
    if length < room_lo:
        return []
    mean_width = _cells(float(rng.uniform(3.5, 6.5)), resolution_m)
    n = max(1, int(round(length / mean_width)))
    while True:
        walls = [int(rng.integers(WALL_CELLS[0], WALL_CELLS[1] + 1)) for _ in range(n - 1)]
        budget = length - sum(walls)
        if budget < n * room_lo and n > 1:
            n -= 1
        elif budget > n * room_hi:
            n += 1
        else:
            break
    widths = _split_length(rng, budget, n, room_lo, room_hi)
    spans, col = [], lo
    for k, width in enumerate(widths):
        spans.append((col, col + width))
        col += width + (walls[k] if k < n - 1 else 0)
    return spans


def _link_neighbours(rooms: list[Room], first: int, west_wall: int, east_wall: int) -> None:
    """Record, for rooms[first:] (one stretch, west to east), the room or cross corridor across
    their side walls."""
    for i in range(first, len(rooms)):
        room = rooms[i]
        if i > first:
            west = rooms[i - 1].interior
            room.beyond["west"] = Beyond("room", i - 1, room.interior.col0 - west.col1)
        elif west_wall:
            room.beyond["west"] = Beyond("corridor", -1, west_wall)
        if i + 1 < len(rooms):
            east = rooms[i + 1].interior
            room.beyond["east"] = Beyond("room", i + 1, east.col0 - room.interior.col1)
        elif east_wall:
            room.beyond["east"] = Beyond("corridor", -1, east_wall)


# ----------------------------------------------------------------------------- doors


@dataclass(frozen=True)
class _Opening:
    """A door to be placed: in which wall of which room, and whether it is the start room's."""

    room: int
    side: str
    narrowest: bool = False


def _corridor_side(room: Room) -> str:
    """The side of a room that faces its row's corridor (every room row faces one)."""
    return next(s for s in ("south", "north") if s in room.beyond)


def _pick_start_room(rng: np.random.Generator, rooms: list[Room], resolution_m: float) -> int:
    """A room at least 4 m a side when there is one, so a small team has room to line up."""
    roomy = _cells(4.0, resolution_m)
    candidates = [i for i, r in enumerate(rooms)
                  if min(r.interior.height_cells, r.interior.width_cells) >= roomy]
    candidates = candidates or list(range(len(rooms)))
    return int(candidates[int(rng.integers(len(candidates)))])


def _openings(rng: np.random.Generator, rooms: list[Room], start_room: int, resolution_m: float) -> list[_Opening]:
    """Every door the floor gets: a corridor door for each room but the inner ones, a door
    from each inner room to its gateway, then the second doors."""
    inner = _pick_inner_rooms(rng, rooms, start_room)
    openings = [
        _Opening(i, inner[i]) if i in inner else _Opening(i, _corridor_side(room), narrowest=(i == start_room))
        for i, room in enumerate(rooms)
    ]
    return openings + _second_doors(rng, rooms, start_room, inner, openings, resolution_m)


def _pick_inner_rooms(rng: np.random.Generator, rooms: list[Room], start_room: int) -> dict[int, str]:
    """Rooms entered only through the room next door: inner room -> the side its gateway is on.

    A gateway is an ordinary room (never the start room, never itself inner) and serves one
    inner room, so every inner room is one door away from a room with a corridor door."""
    target = max(1, int(round(SHARE_INNER_ROOMS * len(rooms))))
    inner: dict[int, str] = {}
    gateways: set[int] = set()
    for i in rng.permutation(len(rooms)):
        i = int(i)
        if len(inner) >= target:
            break
        if i == start_room or i in gateways:
            continue
        sides = [s for s in ("west", "east")
                 if s in rooms[i].beyond and rooms[i].beyond[s].kind == "room"
                 and rooms[i].beyond[s].room not in (start_room, *inner, *gateways)]
        if sides:
            side = sides[int(rng.integers(len(sides)))]
            inner[i] = side
            gateways.add(rooms[i].beyond[side].room)
    return inner


def _second_doors(rng: np.random.Generator, rooms: list[Room], start_room: int, inner: dict[int, str],
                  openings: list[_Opening], resolution_m: float) -> list[_Opening]:
    """A second door for some rooms with a corridor door: another to the corridor (when the wall
    takes two of the widest), one to a cross corridor, or one to a room next door that is not
    the start room and not joined to this one yet."""
    target = max(1, int(round(SHARE_TWO_DOOR_ROOMS * len(rooms))))
    two_slots = 2 * (_clear_cells(WIDE_DOOR_M, resolution_m) + 2 * _cells(DOOR_JAMB_M, resolution_m)) + 1
    joined = {frozenset((o.room, rooms[o.room].beyond[o.side].room)) for o in openings
              if rooms[o.room].beyond[o.side].kind == "room"}
    extra: list[_Opening] = []
    for i in rng.permutation(len(rooms)):
        i = int(i)
        if len(extra) >= target:
            break
        if i == start_room or i in inner:
            continue
        room = rooms[i]
        options = [_corridor_side(room)] if room.interior.width_cells >= two_slots else []
        for side in ("west", "east"):
            beyond = room.beyond.get(side)
            if beyond is None:
                continue
            if beyond.kind == "corridor" or (beyond.room != start_room
                                             and frozenset((i, beyond.room)) not in joined):
                options.append(side)
        if options:
            side = options[int(rng.integers(len(options)))]
            extra.append(_Opening(i, side))
            if room.beyond[side].kind == "room":
                joined.add(frozenset((i, room.beyond[side].room)))
    return extra


def _wall_span(interior: CellRect, side: str) -> tuple[int, int]:
    """The cells along a wall of a room's interior: columns for south/north, rows for west/east."""
    return (interior.col0, interior.col1) if side in ("south", "north") else (interior.row0, interior.row1)


def _through_wall(interior: CellRect, side: str, along0: int, along1: int, depth: int) -> CellRect:
    """The cells `depth` deep beyond a room's wall on `side`, at along0..along1 along it."""
    if side == "north":
        return CellRect(interior.row1, interior.row1 + depth, along0, along1)
    if side == "south":
        return CellRect(interior.row0 - depth, interior.row0, along0, along1)
    if side == "east":
        return CellRect(along0, along1, interior.col1, interior.col1 + depth)
    return CellRect(along0, along1, interior.col0 - depth, interior.col0)


def _inside_wall(interior: CellRect, side: str, along0: int, along1: int, depth: int) -> CellRect | None:
    """The room's own cells up to `depth` in from its wall on `side`, at along0..along1 along it."""
    if side == "north":
        rect = CellRect(interior.row1 - depth, interior.row1, along0, along1)
    elif side == "south":
        rect = CellRect(interior.row0, interior.row0 + depth, along0, along1)
    elif side == "east":
        rect = CellRect(along0, along1, interior.col1 - depth, interior.col1)
    else:
        rect = CellRect(along0, along1, interior.col0, interior.col0 + depth)
    return rect.clipped_to(interior)


_OPPOSITE = {"south": "north", "north": "south", "west": "east", "east": "west"}


def _place_doors(rng: np.random.Generator, rooms: list[Room], openings: list[_Opening],
                 resolution_m: float) -> list[Door]:
    """Each opening as a door: its width drawn from the narrowest (the body's diameter and
    0.1 m) to WIDE_DOOR_M, the start room's exactly the narrowest, at a random place along its
    wall with DOOR_JAMB_M of wall to each corner. Two doors in one wall take one half each."""
    narrowest = _clear_cells(NARROW_DOOR_M, resolution_m)
    widest = _clear_cells(WIDE_DOOR_M, resolution_m)
    jamb = _cells(DOOR_JAMB_M, resolution_m)
    walls: dict[tuple[int, str], list[_Opening]] = {}
    for opening in openings:
        walls.setdefault((opening.room, opening.side), []).append(opening)
    doors = []
    for (index, side), in_wall in walls.items():
        room = rooms[index]
        beyond = room.beyond[side]
        lo, hi = _wall_span(room.interior, side)
        slot = (hi - lo) // len(in_wall)
        for k, opening in enumerate(in_wall):
            s0, s1 = lo + k * slot, lo + (k + 1) * slot
            room_for = s1 - s0 - 2 * jamb
            width = narrowest if opening.narrowest else int(rng.integers(narrowest, min(widest, room_for) + 1))
            at = int(rng.integers(s0 + jamb, s1 - jamb - width + 1))
            doors.append(Door(opening=_through_wall(room.interior, side, at, at + width, beyond.wall_cells),
                              clear_cells=width, side=side, room=index, other_room=beyond.room))
    return doors


def _door_aprons(rooms: list[Room], doors: list[Door], resolution_m: float) -> list[list[CellRect]]:
    """Per room, the cells in front of its doors kept free of furniture: DOOR_APRON_M deep and
    DOOR_JAMB_M wider than the door on each side, so the body can turn in and out of it."""
    depth = _cells(DOOR_APRON_M, resolution_m)
    jamb = _cells(DOOR_JAMB_M, resolution_m)
    aprons: list[list[CellRect]] = [[] for _ in rooms]
    for door in doors:
        along0, along1 = ((door.opening.col0, door.opening.col1) if door.side in ("south", "north")
                          else (door.opening.row0, door.opening.row1))
        for index, side in ((door.room, door.side), (door.other_room, _OPPOSITE[door.side])):
            if index < 0:
                continue
            apron = _inside_wall(rooms[index].interior, side, along0 - jamb, along1 + jamb, depth)
            if apron is not None:
                aprons[index].append(apron)
    return aprons


# ----------------------------------------------------------------------------- furniture


@dataclass(frozen=True, eq=False)
class _Piece:
    """A piece of furniture: its bounding box on the map grid, which cells of it are solid, and
    the narrow gap it was set to leave beside another piece, if it was."""

    box: CellRect
    solid: np.ndarray  # bool, the box's shape
    squeeze: Squeeze | None = None


def _furnish_room(rng: np.random.Generator, free: np.ndarray, room: Room, aprons: list[CellRect],
                  resolution_m: float, staging: bool = False) -> list[Squeeze]:
    """Furniture for one room, drawn and kept piece by piece (see _place_one): desks and
    cabinets against the walls, a table in a large room, chairs and pillars in the open, then
    pillars set a squeeze gap from furniture already there. Returns the squeezes kept.

    The staging room (the start room) gets the pieces against the walls only: its middle is
    where a team lines up (map_spec.staging_poses), and no team can line up outside it."""
    interior = room.interior
    area_m2 = interior.height_cells * interior.width_cells * resolution_m ** 2
    placed: list[_Piece] = []

    def place(count: int, draw) -> None:
        for _ in range(count):
            # the squeezes kept so far stay as narrow as recorded: nothing more goes in them
            keep_clear = aprons + [p.squeeze.gap for p in placed if p.squeeze is not None]
            piece = _place_one(free, room, aprons, keep_clear, resolution_m, draw)
            if piece is not None:
                placed.append(piece)

    place(1 + int(area_m2 // 8.0), lambda: _wall_piece(rng, interior, resolution_m))
    if staging:
        return []
    if min(interior.height_cells, interior.width_cells) >= _cells(4.5, resolution_m) and rng.random() < 0.6:
        place(1, lambda: _table_piece(rng, interior, resolution_m))
    place(1 + int(area_m2 // 6.0), lambda: _blob_piece(rng, interior, resolution_m))
    place(1 + int(area_m2 // 25.0), lambda: _squeeze_piece(rng, free, interior, placed, resolution_m))
    return [piece.squeeze for piece in placed if piece.squeeze is not None]


def _place_one(free: np.ndarray, room: Room, aprons: list[CellRect], keep_clear: list[CellRect],
               resolution_m: float, draw) -> _Piece | None:
    """Draw a piece (draw() -> _Piece or None) up to PLACEMENT_TRIES times until one fits (see
    _fits) and leaves the room passable (see _keep_if_passable); it is then set into `free`."""
    for _ in range(PLACEMENT_TRIES):
        piece = draw()
        if piece is not None and _fits(free, room.interior, keep_clear, piece) \
                and _keep_if_passable(free, room, aprons, piece, resolution_m):
            return piece
    return None


def _fits(free: np.ndarray, interior: CellRect, keep_clear: list[CellRect], piece: _Piece) -> bool:
    """Inside the room, on free floor, off the cells kept clear (door aprons, squeeze gaps)."""
    if piece.box.clipped_to(interior) != piece.box:
        return False
    if not free[piece.box.index][piece.solid].all():
        return False
    for rect in keep_clear:
        overlap = piece.box.clipped_to(rect)
        if overlap is not None:
            local = piece.solid[overlap.row0 - piece.box.row0:overlap.row1 - piece.box.row0,
                                overlap.col0 - piece.box.col0:overlap.col1 - piece.box.col0]
            if local.any():
                return False
    return True


def _keep_if_passable(free: np.ndarray, room: Room, aprons: list[CellRect], piece: _Piece,
                      resolution_m: float) -> bool:
    """Set the piece into `free` if the places the body can stand in the room (between cell
    centres too, see body_lattice_factor) stay one 4-connected piece that reaches in front of
    every door, and into the squeeze gap the piece was set to leave (a gap the body cannot
    stand in is a sliver, not a squeeze); otherwise leave `free` as it was.

    Judged on the room alone (its walls and doors closed), so it never depends on the order
    rooms are furnished in; opening the doors only adds places to stand."""
    interior = room.interior
    window = free[interior.index]
    under = window[piece.box.row0 - interior.row0:piece.box.row1 - interior.row0,
                   piece.box.col0 - interior.col0:piece.box.col1 - interior.col0]
    under[piece.solid] = False
    factor = body_lattice_factor(resolution_m)
    centres = _body_centres(_subcells(window, factor), resolution_m / factor, BODY_RADIUS_M)
    _, pieces = ndimage.label(centres)
    must_reach = aprons + ([piece.squeeze.gap] if piece.squeeze is not None else [])
    reaches = all(centres[factor * (r.row0 - interior.row0):factor * (r.row1 - interior.row0),
                          factor * (r.col0 - interior.col0):factor * (r.col1 - interior.col0)].any()
                  for r in must_reach)
    if pieces == 1 and reaches:
        return True
    under[piece.solid] = True
    return False


def _random_box(rng: np.random.Generator, interior: CellRect, height: int, width: int) -> CellRect | None:
    """A height x width box at a random place inside the room, or None if it cannot fit."""
    if height > interior.height_cells or width > interior.width_cells:
        return None
    row0 = int(rng.integers(interior.row0, interior.row1 - height + 1))
    col0 = int(rng.integers(interior.col0, interior.col1 - width + 1))
    return CellRect(row0, row0 + height, col0, col0 + width)


def _wall_piece(rng: np.random.Generator, interior: CellRect, resolution_m: float) -> _Piece | None:
    """A desk (1.2-1.8 m by 0.6-0.8 m) or a cabinet (0.8-2.0 m by 0.4-0.6 m) flush against a
    random wall, as furniture stands in offices: no gap behind it to get stuck in."""
    if rng.random() < 0.5:
        length_m, depth_m = rng.uniform(1.2, 1.8), rng.uniform(0.6, 0.8)
    else:
        length_m, depth_m = rng.uniform(0.8, 2.0), rng.uniform(0.4, 0.6)
    length, depth = _cells(length_m, resolution_m), _cells(depth_m, resolution_m)
    side = _SIDES[int(rng.integers(4))]
    lo, hi = _wall_span(interior, side)
    if hi - lo < length:
        return None
    at = int(rng.integers(lo, hi - length + 1))
    box = _inside_wall(interior, side, at, at + length, depth)
    if box is None or box.height_cells * box.width_cells != length * depth:
        return None
    return _Piece(box, np.ones((box.height_cells, box.width_cells), dtype=bool))


def _table_piece(rng: np.random.Generator, interior: CellRect, resolution_m: float) -> _Piece | None:
    """A meeting table, 0.8-1.2 m by 1.6-2.4 m, either way round, somewhere in the room."""
    short, long_ = _cells(rng.uniform(0.8, 1.2), resolution_m), _cells(rng.uniform(1.6, 2.4), resolution_m)
    height, width = (short, long_) if rng.random() < 0.5 else (long_, short)
    box = _random_box(rng, interior, height, width)
    return None if box is None else _Piece(box, np.ones((height, width), dtype=bool))


def _blob_shape(rng: np.random.Generator, size: int) -> np.ndarray:
    """A chair (a disc) or a pillar (a square), `size` cells across."""
    if rng.random() < 0.5:
        return np.ones((size, size), dtype=bool)
    offsets = np.arange(size) - (size - 1) / 2.0
    return offsets[:, None] ** 2 + offsets[None, :] ** 2 <= (size / 2.0) ** 2


def _blob_size(rng: np.random.Generator, resolution_m: float) -> int:
    """0.3 to 0.6 m across, in whole cells."""
    return int(rng.integers(_cells(0.3, resolution_m), _cells(0.6, resolution_m) + 1))


def _blob_piece(rng: np.random.Generator, interior: CellRect, resolution_m: float) -> _Piece | None:
    """A chair or pillar at a random place in the room."""
    size = _blob_size(rng, resolution_m)
    shape = _blob_shape(rng, size)
    box = _random_box(rng, interior, size, size)
    return None if box is None else _Piece(box, shape)


def _squeeze_piece(rng: np.random.Generator, free: np.ndarray, interior: CellRect, placed: list[_Piece],
                   resolution_m: float) -> _Piece | None:
    """A square pillar set beside a piece already placed, with a gap as narrow as the narrowest
    door (or one cell more) between their faces, the pillar level with the piece across the gap
    so the gap is that wide all along; None if the gap is not all free floor inside the room."""
    # beside a solid rectangle only: a chair's round edge would leave the gap wider at its ends
    blocks = [p.box for p in placed if p.solid.all()]
    if not blocks:
        return None
    other = blocks[int(rng.integers(len(blocks)))]
    size = _blob_size(rng, resolution_m)
    gap = _clear_cells(NARROW_DOOR_M, resolution_m) + int(rng.integers(2))
    side = _SIDES[int(rng.integers(4))]
    if side in ("south", "north"):
        if other.width_cells < size:
            return None
        col0 = int(rng.integers(other.col0, other.col1 - size + 1))
        row0 = other.row0 - gap - size if side == "south" else other.row1 + gap
        box = CellRect(row0, row0 + size, col0, col0 + size)
        between = CellRect(min(box.row1, other.row1), max(box.row0, other.row0), col0, col0 + size)
        faces_apart_in_y = True
    else:
        if other.height_cells < size:
            return None
        row0 = int(rng.integers(other.row0, other.row1 - size + 1))
        col0 = other.col0 - gap - size if side == "west" else other.col1 + gap
        box = CellRect(row0, row0 + size, col0, col0 + size)
        between = CellRect(row0, row0 + size, min(box.col1, other.col1), max(box.col0, other.col0))
        faces_apart_in_y = False
    if between.clipped_to(interior) != between or not free[between.index].all():
        return None
    return _Piece(box, np.ones((size, size), dtype=bool), Squeeze(between, gap, faces_apart_in_y))


# ----------------------------------------------------------------------------- finishing


def _start_cell(free: np.ndarray, start_room: Room, resolution_m: float) -> tuple[int, int]:
    """The cell of the start room farthest from walls and furniture (first in row-major order
    on ties): where the body fits best, and a small team has room around it."""
    interior = start_room.interior
    clearance = clearance_field_m(free[interior.index], resolution_m)
    row, col = np.unravel_index(int(np.argmax(clearance)), clearance.shape)
    return interior.row0 + int(row), interior.col0 + int(col)


def _seal_pockets(free: np.ndarray, start_rc: tuple[int, int]) -> None:
    """Turn to wall the free cells furniture has closed in on every side (not even 8-connected
    to the start): floor nobody can reach or see into, as in the other generators' one piece."""
    labels, count = ndimage.label(free, structure=_EIGHT_CONNECTED)
    if count > 1:
        np.equal(labels, labels[start_rc], out=free)


def _check_rooms_reachable(floor: OfficeFloor) -> None:
    """RuntimeError unless the body, from the start, reaches every place it can stand in each
    room (body_reachable, 4-connected as missions are scored)."""
    occ = floor.occ
    swept = body_reachable(occ, floor.start[:2])
    for index, room in enumerate(floor.rooms):
        centres = body_centres_in(occ.free[room.interior.index], occ.resolution_m)
        if not swept[room.interior.index][centres].all():
            raise RuntimeError(f"{occ.name}: room {index} at {room.interior} is not reachable by the "
                               f"body from the start (generator bug)")


# ----------------------------------------------------------------------------- the body between cell centres


def body_lattice_factor(resolution_m: float) -> int:
    """Into how many parts each cell's side is cut where the body's centre may stand: the
    fewest that let a body of BODY_RADIUS_M through the narrowest door (2 at 0.1 m cells).

    On whole cells the middle of a door an even number of cells wide is a cell edge, where no
    cell centre lies: standing on cell centres, a body of radius 0.25 m needs 0.7 m of free
    cells at 0.1 m, though a 0.6 m door leaves it 5 cm either side and the simulated body
    (world_sim.kinematics) drives through. A finer lattice of centres puts one near the middle."""
    door = _clear_cells(NARROW_DOOR_M, resolution_m)
    for factor in range(1, 9):
        footprint = _body_footprint(resolution_m / factor, BODY_RADIUS_M)
        if door * factor >= footprint[footprint.shape[0] // 2].sum():  # its width across a door
            return factor
    raise ValueError(f"no lattice up to 8 parts a cell fits the body through a door at {resolution_m!r} m cells")


def _subcells(grid: np.ndarray, factor: int) -> np.ndarray:
    """The grid with each cell cut into factor x factor parts of the same value."""
    return grid.repeat(factor, axis=0).repeat(factor, axis=1)


def _any_subcell(fine: np.ndarray, factor: int) -> np.ndarray:
    """Back to whole cells: a cell is True where any of its parts is."""
    rows, cols = fine.shape[0] // factor, fine.shape[1] // factor
    return fine.reshape(rows, factor, cols, factor).any(axis=(1, 3))


def body_reachable(occ: OccupancyMap, start_xy: tuple[float, float], robot_radius_m: float = BODY_RADIUS_M,
                   connectivity: int = 4) -> np.ndarray:
    """The cells a robot body of that radius sweeps from the start: reachable_free's answer with
    the body's centre on the lattice of body_lattice_factor(resolution), at the map's cells."""
    factor = body_lattice_factor(occ.resolution_m)
    fine = OccupancyMap(free=_subcells(occ.free, factor), resolution_m=occ.resolution_m / factor,
                        origin_x_m=occ.origin_x_m, origin_y_m=occ.origin_y_m, name=occ.name)
    swept = reachable_free(fine, start_xy, connectivity=connectivity, robot_radius_m=robot_radius_m)
    return _any_subcell(swept, factor)


def body_centres_in(free: np.ndarray, resolution_m: float, robot_radius_m: float = BODY_RADIUS_M) -> np.ndarray:
    """The cells of `free` (outside it wall) where the body's centre may stand somewhere, on
    the lattice of body_lattice_factor(resolution)."""
    factor = body_lattice_factor(resolution_m)
    return _any_subcell(_body_centres(_subcells(free, factor), resolution_m / factor, robot_radius_m), factor)


def _body_footprint(lattice_m: float, radius_m: float) -> np.ndarray:
    """The lattice cells counted as under a body centred on the middle one: each cell whose
    square comes within radius_m of the centre (the world's collision test,
    world_sim.kinematics.ClearanceMap.disc_fits, where touching counts), and each cell whose
    centre lies within the radius rounded up to whole cells (reachable_free's disc). The union
    is stricter than either, so where it lets the body through, so do the world and
    reachable_free (both check the floor: the world drives it, missions are scored by it)."""
    r_cells = radius_m / lattice_m
    n = max(1, int(np.ceil(r_cells)))  # reachable_free's rounding; the exact test never reaches farther
    offsets = np.arange(-n, n + 1, dtype=np.float64)
    gap = np.maximum(np.abs(offsets) - 0.5, 0.0)
    touched = np.hypot(gap[:, None], gap[None, :]) <= r_cells + 1e-9
    within_rounded = offsets[:, None] ** 2 + offsets[None, :] ** 2 <= n * n
    return touched | within_rounded


def _body_centres(free: np.ndarray, lattice_m: float, radius_m: float) -> np.ndarray:
    """The cells of a grid of lattice_m cells whose centre the body fits on: none of its
    _body_footprint is wall (outside the grid is wall)."""
    return ndimage.binary_erosion(free, structure=_body_footprint(lattice_m, radius_m), border_value=0)
