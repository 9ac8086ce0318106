"""The paper's own merge, as an ablation (`mrtopomap:literal`, mrtopomap.md 1.5 and 5.3's
literal mode): Algorithm 2 line 11 and Fig. 4's correction, nothing more.

Every pair (own-built vertex v_i, teammate's vertex v_alpha) whose descriptors score
th_merge or more gives one translation T = p_i - p_alpha (no rotation: the authors' robots
shared one Gazebo frame and never needed one). Pairs are looked at as records come: each
teammate vertex received against the own vertices held, and each own vertex built against
the teammate vertices held, in that order, so the result depends on arrival order, as the
paper's does. The first translation merges the maps at once; from three on, SMMR's rule
(the paper's reference [6]): per component, mean and standard deviation over the samples;
every sample farther than 0.9 standard deviations from the mean in any component is
dropped, once; the mean of the rest is the transform (all samples when none is left).

The result has the shape of merge.MergeResult, so the scheme treats both merges alike.
"""
from __future__ import annotations

import math

import numpy as np

from firmware.schemes.mr_topomap import descriptor as desc
from firmware.schemes.mr_topomap.merge import SE2, MergeResult, TeammateVertices, VertexSet
from firmware.schemes.mr_topomap.params import DEFAULT, MrTopoParams
from firmware.schemes.mr_topomap.records import Vertex

SMMR_SIGMA = 0.9          # SMMR's outlier rule: farther than this many std from the mean


def smmr_mean(samples: np.ndarray) -> np.ndarray:
    """SMMR's estimate from translation samples (n, 2): the first one below three samples;
    else the mean of those within SMMR_SIGMA std of the mean in every component (all of them
    if none is)."""
    s = np.asarray(samples, dtype=np.float64).reshape(-1, 2)
    if len(s) < 3:
        return s[0].copy()
    mean, std = s.mean(axis=0), s.std(axis=0)
    keep = (np.abs(s - mean) <= SMMR_SIGMA * std).all(axis=1)
    return s[keep].mean(axis=0) if keep.any() else mean


class LiteralMerge(TeammateVertices):
    """One teammate's vertices and the translation-only merge of its frame (order-dependent)."""

    def __init__(self, owner: int, params: MrTopoParams = DEFAULT) -> None:
        super().__init__(owner)
        self.p = params
        self._order: list[tuple[int, int]] = []         # keys in arrival order
        self._pending: list[tuple[int, int]] = []       # received, not yet matched against the own vertices
        self._own_seen = 0                              # own vertices already matched against the held ones
        self.samples: list[tuple[float, float]] = []
        self.merges = self.unmerges = self.corrections = 0
        self._last_T: SE2 | None = None

    def add(self, v: Vertex) -> bool:
        first = v.key not in self._records
        if not super().add(v):
            return False
        if first:
            self._order.append(v.key)
            self._pending.append(v.key)
        return True

    def _match(self, own_codes: np.ndarray, own_xy: np.ndarray, theirs: list[Vertex]) -> None:
        """Translations of every (own, theirs) pair scoring th_merge or more, theirs in the
        given order, own in index order."""
        if not len(own_codes) or not theirs:
            return
        scores = desc.peaks(desc.shift_scores(desc.centred(own_codes),
                                              desc.centred(np.array([v.desc.codes for v in theirs])))
                            )[0]                                           # (own, theirs)
        for b, v in enumerate(theirs):
            for a in np.flatnonzero(scores[:, b] >= self.p.th_merge):
                self.samples.append((float(own_xy[a, 0] - v.x_m), float(own_xy[a, 1] - v.y_m)))

    def update(self, own: VertexSet, grid=None, own_map=None, own_map_token=None) -> MergeResult:
        """Match what came since the last call: new teammate vertices against every own vertex
        (own vertices in id order), then own vertices built since against every teammate vertex
        held before them."""
        own_vs = sorted(own.vertices, key=lambda v: v.vid)
        own_codes = np.array([v.desc.codes for v in own_vs]).reshape(-1, desc.BINS)
        own_xy = np.array([[v.x_m, v.y_m] for v in own_vs]).reshape(-1, 2)
        held_before = [self._records[k] for k in self._order if k not in set(self._pending)]
        fresh_own = slice(self._own_seen, len(own_vs))
        self._match(own_codes[fresh_own], own_xy[fresh_own], held_before)
        self._own_seen = len(own_vs)
        self._match(own_codes, own_xy, [self._records[k] for k in self._pending])
        self._pending = []
        if not self.samples:
            return MergeResult(False, None, 0, 0, "no hypotheses", (), (), 0, ())
        t = smmr_mean(np.array(self.samples))
        T = SE2(0.0, float(t[0]), float(t[1]))
        if self._last_T is None:
            self.merges += 1
        elif math.hypot(T.tx - self._last_T.tx, T.ty - self._last_T.ty) > self.p.cluster_sep_m:
            self.corrections += 1
        self._last_T = T
        return MergeResult(True, T, len(self.samples), 0, "merged", (), (), len(self.samples), ())
