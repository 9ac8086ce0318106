"""Meier, Stachniss, Burgard (ECMR 2005): polygon maps under a split-rate budget, with
target broadcast and a utility discount (issue 22; `../shared/schemes/meier.md`).

Being built. So far: the boundary of the observed area as crack contours (contours.py),
Douglas-Peucker by edge splits, worst edge first, one split at a time (simplify.py), the
polygon map following the boundary from one map to the next with a number of splits
(tracker.py), the records that tell it (polygons.py) and a receiver's copy as a pure
function of the records it holds (replica.py). Still to come: the split rate's token bucket
on the robot's global coarse raster, the records' codec in the scheme's dialect,
rasterising teammates' polygons, and the coordination of eq. (1) and Algorithm 1. The
scheme is not in the registry.
"""
