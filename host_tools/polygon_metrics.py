"""How well a team's polygon maps (Meier et al., firmware.schemes.meier) tell each robot
what the others saw: the approximation error of meier.md A17 and each robot's copy of each
teammate's polygons against the original. Asked of every scheme with polygon maps (those
answering `polygons`); others get none."""
from __future__ import annotations

import numpy as np

from firmware import kernels
from firmware.schemes.meier.contours import WALL_EDGE
from firmware.schemes.meier.raster import rasterise_rings


def has_polygons(agents: list) -> bool:
    return bool(agents) and all(hasattr(a.scheme, "polygons") and a.scheme.observed() is not None for a in agents)


def _on(grid: tuple[np.ndarray, int, int] | None, r0: int, c0: int, shape: tuple[int, int]) -> np.ndarray:
    """`grid` (cells, row0, col0) on the box of `shape` at (r0, c0); unknown outside it."""
    out = np.zeros(shape, np.uint8)
    if grid is None:
        return out
    cells, g_r0, g_c0 = grid
    r_lo, c_lo = max(r0, g_r0), max(c0, g_c0)
    r_hi, c_hi = min(r0 + shape[0], g_r0 + cells.shape[0]), min(c0 + shape[1], g_c0 + cells.shape[1])
    if r_hi > r_lo and c_hi > c_lo:
        out[r_lo - r0:r_hi - r0, c_lo - c0:c_hi - c0] = cells[r_lo - g_r0:r_hi - g_r0, c_lo - g_c0:c_hi - g_c0]
    return out


def approximation_errors(agents: list) -> list[float]:
    """Per robot: the share of the cells known in the central map (every robot's own
    observations together, occupied over free) that its combined map (its own observations,
    else what its teammates' polygons say) gets wrong or leaves unknown (meier.md A17)."""
    observed = [a.scheme.observed() for a in agents]
    r0 = min(o[1] for o in observed)
    c0 = min(o[2] for o in observed)
    r1 = max(o[1] + o[0].shape[0] for o in observed)
    c1 = max(o[2] + o[0].shape[1] for o in observed)
    shape = (r1 - r0, c1 - c0)
    own = [_on(o, r0, c0, shape) for o in observed]
    central = np.maximum.reduce(own)
    known = central != kernels.UNKNOWN
    n_known = int(known.sum())
    out = []
    for a, mine in zip(agents, own):
        combined = np.where(mine != kernels.UNKNOWN, mine, _on(a.scheme.team_layer(), r0, c0, shape))
        out.append(float((combined[known] != central[known]).sum()) / n_known if n_known else 0.0)
    return out


def replica_mismatch(agents: list) -> tuple[list[list[float | None]], list[list[float | None]]]:
    """[receiver][sender], None on the diagonal and where the sender has no vertex: the
    share of the area the sender's polygons say something about (free or wall) that the
    receiver's copy, drawn the same way, says otherwise; and the share of the sender's live
    vertices that the copy does not hold exactly (same id, place, edge type and successor)."""
    truth = [a.scheme.polygons() for a in agents]
    area, vertices = [], []
    for i, a in enumerate(agents):
        area_row, vertex_row = [], []
        for j, sent in enumerate(truth):
            if i == j or not sent:
                area_row.append(None)
                vertex_row.append(None)
                continue
            held = a.scheme.polygons_of(agents[j].hal.robot_id)
            area_row.append(_area_differing(sent, held))
            sent_states, held_states = _vertex_states(sent), _vertex_states(held)
            vertex_row.append(sum(held_states.get(v) != st for v, st in sent_states.items()) / len(sent_states))
        area.append(area_row)
        vertices.append(vertex_row)
    return area, vertices


def _area_differing(sent, held) -> float:
    """The share of the cells `sent` shows known that `held` shows otherwise (both drawn
    as a receiver draws a teammate's rings)."""
    corners = np.array([(x, y) for ring in sent + held for _, x, y, _ in ring], np.int64)
    (c_lo, r_lo), (c_hi, r_hi) = corners.min(axis=0) - 2, corners.max(axis=0) + 2
    shape = (int(r_hi - r_lo), int(c_hi - c_lo))

    def drawn(rings):
        lattice = [np.array([(x, y) for _, x, y, _ in ring], np.int64) for ring in rings]
        wall = [np.array([t == WALL_EDGE for *_, t in ring]) for ring in rings]
        return rasterise_rings(lattice, wall, shape, int(r_lo), int(c_lo))

    want, got = drawn(sent), drawn(held)
    known = want != kernels.UNKNOWN
    return float((got[known] != want[known]).sum() + (got[~known] != kernels.UNKNOWN).sum()) / max(int(known.sum()), 1)


def _vertex_states(rings) -> dict[int, tuple[int, int, int, int]]:
    """vertex id -> (x_lat, y_lat, edge type, successor id)."""
    return {v[0]: (v[1], v[2], v[3], ring[(k + 1) % len(ring)][0]) for ring in rings for k, v in enumerate(ring)}


class ErrorSampler:
    """The approximation error sampled during a mission (every every_s of mission time),
    for its time average."""

    def __init__(self, every_s: float = 10.0) -> None:
        self.every_us = int(every_s * 1e6)
        self.samples: list[list[float]] = []
        self._next_us = 0

    def __call__(self, now_us: int, agents: list) -> None:
        if now_us >= self._next_us:
            self.samples.append(approximation_errors(agents))
            self._next_us = now_us + self.every_us

    def mean(self) -> list[float]:
        return np.mean(self.samples, axis=0).tolist() if self.samples else []


def report(agents: list, sampler: ErrorSampler, sim_s: float) -> dict:
    """The mission's polygon-map figures (MissionResult.polygon_maps)."""
    mismatch, vertices_wrong = replica_mismatch(agents)
    pairs = [m for row in mismatch for m in row if m is not None]
    splits = [a.scheme.stats()["edge_splits"] for a in agents]
    return {
        "approximation_error_mean": [round(e, 5) for e in sampler.mean()],
        "approximation_error_end": [round(e, 5) for e in approximation_errors(agents)],
        "replica_mismatch_end": [[None if m is None else round(m, 5) for m in row] for row in mismatch],
        "replica_mismatch_end_max": round(max(pairs), 5) if pairs else None,
        "replica_vertices_wrong_end": [[None if m is None else round(m, 5) for m in row] for row in vertices_wrong],
        "split_rate_hz": [round(n / sim_s, 4) if sim_s > 0 else 0.0 for n in splits],
    }
