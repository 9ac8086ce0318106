"""How right the merges of teammates' frames are (MR-TopoMap, issue 25): the host alone knows
how the robots' odometry frames relate (their start poses with `--frames own`; one frame with
`--frames shared`), and compares every robot's estimate T_n<-j with that truth once a
simulated second.

Asked of every scheme that merges frames (those answering `frame_merges`); others get none.
Per ordered pair (n, j): the RMS over j's vertices (as n holds them, in j's frame) of
|T_est q - T_true q|, and the yaw error |psi_est - psi_true|. A merge is wrong while either
exceeds WRONG_M or WRONG_DEG (mrtopomap.md 5.6). Odometry drift is in the vertices, so it
is in the error too: the truth is the relation of the two frames at the start.
"""
from __future__ import annotations

import math

import numpy as np

WRONG_M = 2.0
WRONG_DEG = 10.0


def has_frame_merges(agents: list) -> bool:
    return bool(agents) and all(hasattr(a.scheme, "frame_merges") for a in agents)


def _se2(x: float, y: float, yaw: float) -> np.ndarray:
    c, s = math.cos(yaw), math.sin(yaw)
    return np.array([[c, -s, x], [s, c, y], [0.0, 0.0, 1.0]])


def true_relations(start_poses: list, frames: str) -> list[list[np.ndarray]]:
    """[n][j]: the homogeneous transform T_true n<-j between robot j's odometry frame and
    robot n's (each own frame has its origin and heading at its robot's start pose)."""
    S = [_se2(*p) if frames == "own" else np.eye(3) for p in start_poses]
    return [[np.linalg.inv(S[n]) @ S[j] for j in range(len(S))] for n in range(len(S))]


def pair_error(T_est, T_true: np.ndarray, q: np.ndarray) -> tuple[float, float]:
    """(RMS m over the points q in j's frame, |yaw error| deg) of an estimate (merge.SE2)."""
    E = _se2(T_est.tx, T_est.ty, T_est.psi)
    if len(q):
        h = np.column_stack([q, np.ones(len(q))])
        d = (h @ E.T)[:, :2] - (h @ T_true.T)[:, :2]
        rms = float(np.sqrt((d * d).sum(axis=1).mean()))
    else:
        rms = float(math.hypot(E[0, 2] - T_true[0, 2], E[1, 2] - T_true[1, 2]))
    psi_true = math.atan2(T_true[1, 0], T_true[0, 0])
    yaw = abs((T_est.psi - psi_true + math.pi) % (2 * math.pi) - math.pi)
    return rms, math.degrees(yaw)


class MergeSampler:
    """Called once a simulated second with the agents (host_tools.mission's observer)."""

    def __init__(self, start_poses: list, frames: str) -> None:
        self.truth = true_relations(start_poses, frames)
        n = len(start_poses)
        self.first_merge_s: dict[tuple[int, int], float] = {}
        self.wrong_s: dict[tuple[int, int], float] = {}            # seconds merged wrongly, in all
        self.wrong_spell_s: dict[tuple[int, int], float] = {}      # the current spell
        self.wrong_longest_s: dict[tuple[int, int], float] = {}
        self.last: dict[tuple[int, int], tuple[float, float]] = {}  # pair -> (rms, yaw) at the last sample
        self.pairs = [(a, b) for a in range(n) for b in range(n) if a != b]
        self._prev_s: float | None = None

    def __call__(self, now_us: int, agents: list) -> None:
        t = now_us / 1e6
        dt = 0.0 if self._prev_s is None else t - self._prev_s
        self._prev_s = t
        self.last = {}
        for n, a in enumerate(agents):
            for j, T in a.scheme.frame_merges().items():
                if not 0 <= j < len(agents) or j == n:
                    continue
                rms, yaw = pair_error(T, self.truth[n][j], a.scheme.teammate_vertex_xy(j))
                self.last[(n, j)] = (rms, yaw)
                self.first_merge_s.setdefault((n, j), t)
        for pair in self.pairs:
            e = self.last.get(pair)
            wrong = e is not None and (e[0] > WRONG_M or e[1] > WRONG_DEG)
            if wrong:
                self.wrong_s[pair] = self.wrong_s.get(pair, 0.0) + dt
                self.wrong_spell_s[pair] = self.wrong_spell_s.get(pair, 0.0) + dt
                self.wrong_longest_s[pair] = max(self.wrong_longest_s.get(pair, 0.0), self.wrong_spell_s[pair])
            else:
                self.wrong_spell_s[pair] = 0.0

    def report(self) -> dict:
        right = {p: e for p, e in self.last.items() if e[0] <= WRONG_M and e[1] <= WRONG_DEG}
        rms = sorted(e[0] for e in self.last.values())
        yaw = sorted(e[1] for e in self.last.values())
        key = lambda p: f"{p[0]}<-{p[1]}"  # noqa: E731
        return {
            "pairs": len(self.pairs),
            "merged_at_end": len(self.last),
            "right_at_end": len(right),
            "wrong_at_end": len(self.last) - len(right),
            "ever_merged": len(self.first_merge_s),
            "ever_wrong": sum(1 for p in self.pairs if self.wrong_s.get(p, 0.0) > 0),
            "wrong_longest_s": round(max(self.wrong_longest_s.values(), default=0.0), 1),
            "rms_m_median": round(float(np.median(rms)), 3) if rms else None,
            "rms_m_max": round(rms[-1], 3) if rms else None,
            "yaw_deg_median": round(float(np.median(yaw)), 2) if yaw else None,
            "yaw_deg_max": round(yaw[-1], 2) if yaw else None,
            "first_merge_s": {key(p): round(t, 1) for p, t in sorted(self.first_merge_s.items())},
            "at_end": {key(p): [round(e[0], 3), round(e[1], 2)] for p, e in sorted(self.last.items())},
        }
