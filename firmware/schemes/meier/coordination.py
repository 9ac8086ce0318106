"""Meier et al.'s coordination (§4, eq. (1), Algorithm 1; meier.md 1.6, A11-A14): every robot
broadcasts the target it chose; a robot lowers the utility of its candidate goals that a
teammate heading for its target t would see, by the probability P(d) that the sensor covers
a cell d from t, and takes the goal of the best utility minus beta times the cost of getting
there.

Utility U starts at 1 and loses P(||t - t'||) for each teammate target t that sees t' (within
max_range, no wall on the straight line in the robot's map where it can tell). The choice
argmax U - beta V is argmin V + (1 - U) / beta: the discount is a penalty in metres of path
(Candidate.penalty_m), so the shared target choice makes it. Priority is the robot id: a
robot discounts only the targets of robots with lower ids (A11), so two robots never yield
to each other; `meier_discount_all` discounts every teammate's.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from firmware.services.grid_paths import lines_of_sight
from firmware.services.local_map import LocalMap
from firmware.services.targets import Candidate

TARGET_SEQ_MOD = 128


def coverage_probability(d_m: np.ndarray | float, max_range_m: float) -> np.ndarray:
    """Eq. (1): P(d) = 1 - d / max_range for d < max_range, else 0."""
    d = np.asarray(d_m, np.float64)
    return np.where(d < max_range_m, 1.0 - d / max_range_m, 0.0)


def seq_newer(a: int, b: int) -> bool:
    """Is target sequence number a newer than b (RFC 1982 on 7 bits)?"""
    d = (a - b) % TARGET_SEQ_MOD
    return 0 < d < TARGET_SEQ_MOD // 2


@dataclass
class TeamTarget:
    x_m: float
    y_m: float
    seq: int
    heard_us: int


class TeamTargets:
    """Teammates' targets as their target records said: the newest per teammate (by its
    sequence number), forgotten when released, when the teammate is done, or expiry_s after
    it was last heard."""

    def __init__(self, expiry_s: float) -> None:
        self.expiry_us = int(expiry_s * 1e6)
        self._targets: dict[int, TeamTarget] = {}
        self._released: dict[int, int] = {}        # teammate -> seq of its newest release

    def heard(self, sender: int, x_m: float, y_m: float, claimed: bool, seq: int, now_us: int) -> None:
        held = self._targets.get(sender)
        last = held.seq if held is not None else self._released.get(sender)
        if last is not None and not seq_newer(seq, last):
            if held is not None and seq == held.seq and claimed:
                held.heard_us = now_us             # a keep-alive of the same target
            return
        if claimed:
            self._targets[sender] = TeamTarget(x_m, y_m, seq, now_us)
        else:
            self._targets.pop(sender, None)
            self._released[sender] = seq

    def forget(self, sender: int) -> None:
        self._targets.pop(sender, None)

    def active(self, now_us: int) -> dict[int, tuple[float, float]]:
        return {k: (t.x_m, t.y_m) for k, t in sorted(self._targets.items())
                if now_us - t.heard_us <= self.expiry_us}


def discount(candidates: list[Candidate], targets: list[tuple[float, float]], local_map: LocalMap,
             sight: np.ndarray, max_range_m: float, beta_per_m: float) -> None:
    """Lower each candidate's utility by P(d) for every target that sees it (Algorithm 1,
    lines 4-6), as Candidate.penalty_m = (1 - U) / beta."""
    if not candidates or not targets:
        return
    cxy = np.array([(c.x_m, c.y_m) for c in candidates], np.float64)
    loss = np.zeros(len(candidates))
    c_ij, c_in = local_map.cells_of(cxy)
    for tx, ty in targets:
        d = np.hypot(cxy[:, 0] - tx, cxy[:, 1] - ty)
        p = coverage_probability(d, max_range_m)
        near = np.nonzero(p > 0.0)[0]
        t_ij, t_in = local_map.cells_of(np.array([[tx, ty]]))
        if t_in[0] and len(near):
            # In the window both ends can be checked for a wall between them.
            check = near[c_in[near]]
            seen = lines_of_sight(sight, np.full(len(check), t_ij[0, 0]), np.full(len(check), t_ij[0, 1]),
                                  c_ij[check, 0], c_ij[check, 1])
            p[check[~seen]] = 0.0
        loss += p
    for c, lost in zip(candidates, loss.tolist()):
        c.penalty_m = lost / beta_per_m
