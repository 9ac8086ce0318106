"""Merges told on the air (`mrlink`, mrtopomap.md 5.1 and A8; not in the paper).

Each robot sends its own direct merges, T_sender<-peer with the consensus behind it, when
one is made, moves or is withdrawn (support 0), and again every `link_period_s`. A robot
then holds several estimates of how a teammate j's frame lies in its own:

- direct: its own merge of j (merge.py);
- inverse: j's link T_j<-me, inverted;
- via i: its own direct merge of a third robot i, composed with i's link T_i<-j, or with
  j's link T_j<-i inverted.

Two estimates agree when they put the centre of j's vertices within cluster_sep_m of each
other and their yaws within cluster_sep_deg. Per teammate the estimates fall into groups of
agreeing ones (in a fixed order, so the outcome depends on the estimates held and nothing
else). A group's weight is the number of independent pieces of evidence in it: the direct
merge and the inverse count once together (both rest on the same places the two robots
saw; a look-alike pair fools both alike, and in a maze two robots held each other's frame
turned, in agreement, for minutes), each robot a composition goes through once more. Then:

- a direct merge stands unless a group that excludes it weighs at least two and more than
  its own group; then it is outvoted, and that group's first estimate takes its place;
- a teammate not merged directly is merged by the heaviest group if it weighs at least two
  and no other group as much (a transitive merge: the robots' areas need not overlap at
  all). One robot's merge alone is not taken up: in a maze a wrong one, adopted by the
  others, spread to the whole team within seconds (maze_a, seed 1).

Only direct merges are sent, so no link echoes a conclusion drawn from links.
"""
from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from firmware.schemes.mr_topomap.merge import SE2, within, wrap
from firmware.schemes.mr_topomap.params import MrTopoParams
from firmware.schemes.mr_topomap.records import DYAW_CODES, MAX_SUPPORT, Link

DIRECT, INVERSE, VIA = "direct", "inverse", "via"
# A direct merge goes on the air again before link_period_s when it moved this much (at the
# centre of the peer's vertices) or turned this much: well inside cluster_sep_m and
# cluster_sep_deg, so what a receiver concludes does not hang on a refit not yet resent.
LINK_MOVE_M = 0.5
LINK_TURN_RAD = math.radians(2.0)


def link_of(sender: int, peer: int, T: SE2, support: int) -> Link:
    """T_sender<-peer as an mrlink record's values (0.1 m, 360/4096 deg; support 0: withdrawn)."""
    lim = (1 << 15) - 1
    dx, dy = (max(-lim, min(lim, int(round(v * 10.0)))) for v in (T.tx, T.ty))
    dyaw = int(round((T.psi % (2.0 * math.pi)) / (2.0 * math.pi) * DYAW_CODES)) % DYAW_CODES
    return Link(sender, peer, dx, dy, dyaw, max(0, min(MAX_SUPPORT, support)))


def transform_of(link: Link) -> SE2:
    """The link's T_sender<-peer."""
    return SE2(float(wrap(link.yaw_rad)), link.dx_dm / 10.0, link.dy_dm / 10.0)


class Estimate(NamedTuple):
    T: SE2              # T_me<-j
    source: str         # DIRECT, INVERSE or VIA
    via: int            # the third robot (VIA), else -1


class Resolved(NamedTuple):
    T: SE2
    source: str         # "direct", "outvoted" (replaced by the heavier group), "transitive"
    estimates: int      # estimates held for this teammate
    agreeing: int       # independent evidence (weight) in the group that decided


def estimates(me: int, j: int, direct: dict[int, SE2], links: dict[tuple[int, int], SE2]) -> list[Estimate]:
    """Every estimate of T_me<-j from the own direct merges and the links heard
    ((sender, peer) -> T_sender<-peer, withdrawn ones left out), in a fixed order."""
    out = []
    if j in direct:
        out.append(Estimate(direct[j], DIRECT, -1))
    if (j, me) in links:
        out.append(Estimate(links[(j, me)].inverse(), INVERSE, -1))
    for i in sorted(direct):
        if i == j:
            continue
        if (i, j) in links:
            out.append(Estimate(direct[i].compose(links[(i, j)]), VIA, i))
        elif (j, i) in links:
            out.append(Estimate(direct[i].compose(links[(j, i)].inverse()), VIA, i))
    return out


def agree(a: SE2, b: SE2, centre_xy: np.ndarray, params: MrTopoParams) -> bool:
    return within(a, b, centre_xy, params.cluster_sep_m, params.cluster_sep_rad)


def weight(group: list[Estimate]) -> int:
    """Independent evidence in a group: the pair's own (direct, inverse) once, each third robot once."""
    return len({e.via for e in group})


def groups(ests: list[Estimate], centre_xy: np.ndarray, params: MrTopoParams) -> list[list[Estimate]]:
    """Estimates in groups: each joins the first group whose first estimate it agrees with."""
    out: list[list[Estimate]] = []
    for e in ests:
        for g in out:
            if agree(g[0].T, e.T, centre_xy, params):
                g.append(e)
                break
        else:
            out.append([e])
    return out


def resolve(me: int, direct: dict[int, SE2], links: dict[tuple[int, int], SE2], centres: dict[int, np.ndarray],
            params: MrTopoParams) -> dict[int, Resolved]:
    """Teammate -> how its frame lies in the own one, for every teammate whose vertices are
    held (centres: the centre of j's vertices in j's frame) and whose estimates decide."""
    out: dict[int, Resolved] = {}
    for j in sorted(centres):
        if j == me:
            continue
        ests = estimates(me, j, direct, links)
        if not ests:
            continue
        gs = sorted(groups(ests, centres[j], params), key=weight, reverse=True)   # stable: first formed first
        if j in direct:
            own = next(g for g in gs if any(e.source == DIRECT for e in g))
            rival = next((g for g in gs if g is not own), None)
            if rival is not None and weight(rival) >= 2 and weight(rival) > weight(own):
                out[j] = Resolved(rival[0].T, "outvoted", len(ests), weight(rival))
            else:
                out[j] = Resolved(direct[j], "direct", len(ests), weight(own))
        elif weight(gs[0]) >= 2 and (len(gs) == 1 or weight(gs[0]) > weight(gs[1])):
            out[j] = Resolved(gs[0][0].T, "transitive", len(ests), weight(gs[0]))
    return out
