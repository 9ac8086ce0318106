"""Draws tests/data/pereira8.pgm and .yaml: the topology of Pereira et al.'s Figs. 1, 3 and
4 (pereira.md 6.3, bar 9), for the paper's scaling experiment.

    start room 1 (6 x 6 m)
    branch A: corridor 2 (1.5 m wide) -> room 3 (5 x 5 m) -> doors (0.9 m) to rooms 4 and 5
    branch B: corridor 6 (1.5 m wide) -> room 7 (5 x 5 m) -> a door (0.9 m) to leaf room 8

0.05 m cells, 24 x 16 m, walls everywhere else. Room 1 is the most open place, so it holds
the map's default start. Run `python tests/data/draw_pereira8.py [FOLDER]` to draw it again;
tests/test_pereira8_map.py checks that the files in the repository are what this draws.
"""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

RESOLUTION_M = 0.05
SIZE_M = (24.0, 16.0)                       # width, height
FREE, WALL = 254, 0
# Free rectangles (x0, x1, y0, y1) in metres, map frame (origin at the lower left corner).
ROOMS = {
    "room 1": (0.5, 6.5, 5.0, 11.0),
    "corridor 2": (6.5, 12.5, 9.0, 10.5),
    "room 3": (12.5, 17.5, 8.0, 13.0),
    "room 4": (12.5, 17.5, 13.2, 15.7),
    "room 5": (17.7, 22.7, 8.0, 13.0),
    "corridor 6": (6.5, 12.5, 5.5, 7.0),
    "room 7": (12.5, 17.5, 2.6, 7.6),
    "room 8": (17.7, 22.2, 2.6, 7.6),
}
DOORS = {                                   # 0.9 m wide, through 0.2 m walls
    ("room 3", "room 4"): (14.55, 15.45, 13.0, 13.2),
    ("room 3", "room 5"): (17.5, 17.7, 10.05, 10.95),
    ("room 7", "room 8"): (17.5, 17.7, 4.65, 5.55),
}
YAML = ("# Pereira et al.'s eight regions (tests/data/draw_pereira8.py)\n"
        "image: pereira8.pgm\nresolution: 0.05\norigin: [0.0, 0.0, 0.0]\nnegate: 0\n"
        "occupied_thresh: 0.65\nfree_thresh: 0.196\n")


def image() -> np.ndarray:
    """The map as PGM grey levels, rows from the top (map_server's order)."""
    w, h = (int(round(s / RESOLUTION_M)) for s in SIZE_M)
    img = np.full((h, w), WALL, np.uint8)
    for x0, x1, y0, y1 in [*ROOMS.values(), *DOORS.values()]:
        c0, c1 = int(round(x0 / RESOLUTION_M)), int(round(x1 / RESOLUTION_M))
        r0, r1 = h - int(round(y1 / RESOLUTION_M)), h - int(round(y0 / RESOLUTION_M))
        img[r0:r1, c0:c1] = FREE
    return img


def pgm_bytes() -> bytes:
    img = image()
    return f"P5\n{img.shape[1]} {img.shape[0]}\n255\n".encode() + img.tobytes()


def write(folder: Path) -> None:
    (folder / "pereira8.pgm").write_bytes(pgm_bytes())
    (folder / "pereira8.yaml").write_text(YAML)


if __name__ == "__main__":
    write(Path(sys.argv[1]) if len(sys.argv) > 1 else Path(__file__).parent)
