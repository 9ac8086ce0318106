"""Divide and conquer (../shared/schemes/wiserx.md B3 and section 5.1; issue 24's baseline for
a team with a slow robot): the area known at deployment is split into as many regions as
robots before the start, every robot by the same rule, so they agree without a word; each
robot explores only its own region and stops when it has nothing left there. Nothing is
sent, and a robot that fails or is slow leaves its region to nobody.

    partition.py   the regions: k-means of the floor plan's cells, weighted by their
                   navigable area, from a deterministic start (no randomness)
    scheme.py      the Scheme: own waypoints outside the own region are dropped
"""
from firmware.schemes.divide.scheme import Divide

__all__ = ["Divide"]
