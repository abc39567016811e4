#!/usr/bin/env python3
"""Draws the shipped simulation map configs/maps/office.pgm (ROS map_server format).

An office floor of 24 m x 16 m: a 4 m wide corridor along y = 6..10 with four rooms
below and three above, each joined to the corridor by a 1.2 m door, and furniture
placed asymmetrically so that no two places look alike to a laser (localisation
needs that). Walls are 0.1 m thick; a 0.5 m band of unknown surrounds the floor.

    scripts/make_office_map.py [OUT.pgm]     # default: configs/maps/office.pgm

The PGM is committed; rerun this only to change the map (and say so in the commit).
"""
import os
import sys

RES = 0.05                  # m per pixel (as in office.yaml)
ORIGIN = (-0.5, -0.5)       # lower-left pixel (as in office.yaml)
W, H = 500, 340             # 25 m x 17 m
FREE, OCC, UNKNOWN = 254, 0, 205
WALL = 0.10

grid = [[UNKNOWN] * W for _ in range(H)]  # grid[iy][ix], iy = 0 at the bottom


def cell(x, y):
    return int((x - ORIGIN[0]) / RES), int((y - ORIGIN[1]) / RES)


def fill_rect(x0, y0, x1, y1, value):
    ix0, iy0 = cell(min(x0, x1), min(y0, y1))
    ix1, iy1 = cell(max(x0, x1), max(y0, y1))
    for iy in range(max(iy0, 0), min(iy1, H - 1) + 1):
        for ix in range(max(ix0, 0), min(ix1, W - 1) + 1):
            grid[iy][ix] = value


def fill_circle(cx, cy, r, value):
    ix0, iy0 = cell(cx - r, cy - r)
    ix1, iy1 = cell(cx + r, cy + r)
    for iy in range(iy0, iy1 + 1):
        for ix in range(ix0, ix1 + 1):
            x = ORIGIN[0] + (ix + 0.5) * RES
            y = ORIGIN[1] + (iy + 0.5) * RES
            if (x - cx) ** 2 + (y - cy) ** 2 <= r * r:
                grid[iy][ix] = value


def hwall(y, x0, x1, doors=()):
    """A horizontal wall at y from x0 to x1, with door gaps (a, b)."""
    xs = [x0]
    for a, b in doors:
        xs += [a, b]
    xs.append(x1)
    for i in range(0, len(xs), 2):
        fill_rect(xs[i], y - WALL / 2, xs[i + 1], y + WALL / 2, OCC)


def vwall(x, y0, y1):
    fill_rect(x - WALL / 2, y0, x + WALL / 2, y1, OCC)


# The floor, then its outer walls.
fill_rect(0, 0, 24, 16, FREE)
hwall(0, 0, 24)
hwall(16, 0, 24)
vwall(0, 0, 16)
vwall(24, 0, 16)
# Corridor walls with doors into the rooms.
hwall(6, 0, 24, doors=[(3.0, 4.2), (9.0, 10.2), (15.0, 16.2), (20.5, 21.7)])
hwall(10, 0, 24, doors=[(4.5, 5.7), (13.0, 14.2), (19.0, 20.2)])
# Rooms below (0-7, 7-13, 13-19, 19-24) and above (0-9, 9-17, 17-24).
for x in (7, 13, 19):
    vwall(x, 0, 6)
for x in (9, 17):
    vwall(x, 10, 16)
# Furniture.
fill_rect(1.5, 1.5, 3.0, 2.5, OCC)        # room A: a table
fill_circle(10.0, 3.0, 0.3, OCC)          # room B: a pillar
fill_rect(14.0, 1.0, 18.0, 1.4, OCC)      # room C: shelves
fill_rect(14.0, 3.0, 15.0, 5.0, OCC)
fill_rect(21.0, 2.0, 23.0, 2.3, OCC)      # room D: an L-shaped bench
fill_rect(22.7, 2.0, 23.0, 4.0, OCC)
fill_rect(3.0, 12.0, 5.0, 13.5, OCC)      # room E: a table and a pillar
fill_circle(7.5, 14.5, 0.25, OCC)
for cx, cy in ((11.0, 12.0), (13.0, 14.0), (15.0, 12.0)):  # room F: a hall with pillars
    fill_circle(cx, cy, 0.2, OCC)
fill_rect(19.0, 14.5, 22.0, 15.2, OCC)    # room G: desks
fill_rect(18.0, 11.0, 18.6, 13.0, OCC)
fill_rect(1.0, 9.3, 1.6, 9.9, OCC)        # corridor: a cabinet at its west end
fill_circle(23.2, 6.8, 0.2, OCC)          # corridor: a bin at its east end

out = sys.argv[1] if len(sys.argv) > 1 else os.path.join(os.path.dirname(__file__), "..", "configs", "maps", "office.pgm")
with open(out, "wb") as f:
    f.write(b"P5\n# RACK-RT office map, drawn by scripts/make_office_map.py\n%d %d\n255\n" % (W, H))
    for iy in reversed(range(H)):  # the image's top row is the highest y
        f.write(bytes(grid[iy]))
print("wrote", out)
