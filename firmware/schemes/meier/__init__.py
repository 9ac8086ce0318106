"""Meier, Stachniss, Burgard (ECMR 2005): polygon maps under a split-rate budget, with
target broadcast and a utility discount (issue 22; `../shared/schemes/meier.md`).

Being built. So far: the receiver's copy of a teammate's polygon map as a pure function of
the records it holds (replica.py), and a sender of the same records (polygons.py) that
tests drive with random edits. The scheme is not in the registry yet.
"""
