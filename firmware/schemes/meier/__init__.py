"""Meier, Stachniss, Burgard (ECMR 2005): polygon maps under a split-rate budget, with
target broadcast and a utility discount (issue 22; `../shared/schemes/meier.md`).

Being built. So far: the boundary of the observed area as crack contours (contours.py),
Douglas-Peucker by edge splits, worst edge first, one split at a time (simplify.py), the
receiver's copy of a teammate's polygon map as a pure function of the records it holds
(replica.py), and a sender of the same records (polygons.py) that tests drive with random
edits. Still to come: the update from one map to the next (vanished points, broken and new
boundaries) that turns contours into those edits under a split rate, the records' codec in
the scheme's dialect, rasterising teammates' polygons, and the coordination of eq. (1) and
Algorithm 1. The scheme is not in the registry.
"""
