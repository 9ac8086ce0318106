"""Meier, Stachniss, Burgard (ECMR 2005): polygon maps under a split-rate budget, with
target broadcast and a utility discount (issue 22; `../shared/schemes/meier.md`).

    contours.py      the boundary of the observed area as crack contours
    simplify.py      Douglas-Peucker by edge splits, the worst edge first
    tracker.py       the polygon map following the boundary from one map to the next
    polygons.py      its rings and the records that tell them
    replica.py       a teammate's polygon map as a pure function of the records held
    records.py       the dialect: poly, poly_alive, target
    raster.py        the coarse lattice: own map into it, rings back into cells
    coordination.py  eq. (1) and Algorithm 1: teammates' targets and the utility discount
    scheme.py        the scheme (variants `polygons`, `targets`; `meier-full` = dense:meier)
"""
