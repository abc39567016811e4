#!/usr/bin/env python3
"""Builds the real-data localisation benchmark sets in this folder from GMapping-corrected
CARMEN logs (acschaefer/ple, data/carmen/NAME-corrected.log.gz; see README.md beside this).

For each log it writes
  NAME.log.gz   CARMEN log: FLASER (the scan, its pose fields = the synthetic odometry),
                ODOM (the same odometry) and TRUEPOS (the corrected pose = the reference,
                then the odometry), one of each per scan, with the log's own times
  NAME.pgm      occupancy grid built from the corrected poses and scans (0.05 m)
  NAME.yaml     ROS map_server description of NAME.pgm (what components/maps reads)

  make_datasets.py SRC_DIR [NAME ...]      (SRC_DIR holds NAME-corrected.log.gz)

Pure Python 3 (no numpy), deterministic: the odometry noise comes from random.Random
with a fixed seed per dataset, so a rerun writes the same files.

Scan geometry: FLASER beams evenly from -90 to +90 degrees (step pi / (n - 1)), the
convention of components/replay's CARMEN reader; readings at or above the log's
maximum (no echo) are no-returns.

Map: every reading ray-cast from the corrected pose (Bresenham over 0.05 m cells):
cells passed are 'missed', the end cell 'hit' (no-returns clear nothing). A cell is
occupied when hits >= 2 and hits / (hits + misses) >= 0.25, free when it was passed
at least twice and is not occupied, unknown otherwise. Rays are cast up to
MAP_RANGE (20 m): far readings of a 2-D laser graze the floor and tables.

Odometry error model (per scan step; d = reference translation, a = |rotation| of
the step, both in the frame of the previous pose):
  translation: d * (1 + SCALE) + N(0, K_TT * d + K_TR * a) along, N(0, 0.5 * (K_TT * d)) across
  rotation:    dtheta + BIAS_PER_M * d + N(0, K_RR * a + K_RT * d)
  stalls:      with P_STALL per step the read-out is stale: only a fraction u of the
               step (uniform in STALL_MIN..STALL_MAX) is reported at the scan, the
               rest arrives with the next step (a catch-up), as a wheel-encoder
               read-out that stalls and then reports the accumulated counts. With the
               scans about 1 m apart this is a 0.2-0.7 m error for one scan.
"""
import gzip
import math
import random
import sys

RES = 0.05
MAP_RANGE = 20.0
MARGIN = 1.0
SCALE = 0.01        # 1 % wheel-radius error
BIAS_PER_M = 0.005  # rad/m systematic heading drift (wheel base error)
K_TT = 0.05         # m/m
K_TR = 0.01         # m/rad
K_RR = 0.05         # rad/rad
K_RT = 0.02         # rad/m
P_STALL = 0.05     # per step
STALL_MIN = 0.3    # fraction of a stalled step reported on time
STALL_MAX = 0.8


def parse(path):
    scans = []  # (t, x, y, th, ranges)
    maxr = 0.0
    with gzip.open(path, 'rt') as f:
        for line in f:
            w = line.split()
            if not w or w[0] != 'FLASER':
                continue
            n = int(w[1])
            r = [float(v) for v in w[2:2 + n]]
            rest = w[2 + n:]
            scans.append((float(rest[6]), float(rest[0]), float(rest[1]), float(rest[2]), r))
            maxr = max(maxr, max(r))
    return scans, maxr


def rel(a, b):
    dx, dy = b[0] - a[0], b[1] - a[1]
    c, s = math.cos(a[2]), math.sin(a[2])
    return c * dx + s * dy, -s * dx + c * dy, math.remainder(b[2] - a[2], 2 * math.pi)


def compose(a, d):
    c, s = math.cos(a[2]), math.sin(a[2])
    return a[0] + c * d[0] - s * d[1], a[1] + s * d[0] + c * d[1], math.remainder(a[2] + d[2], 2 * math.pi)


def odometry(poses, seed):
    rng = random.Random(seed)
    odo = [(0.0, 0.0, 0.0)]
    late = None  # the part of a step a stalled read-out has not reported yet
    stalls = 0
    for i in range(1, len(poses)):
        dx, dy, dth = rel(poses[i - 1], poses[i])
        d = math.hypot(dx, dy)
        a = abs(dth)
        along = d * (1 + SCALE) + rng.gauss(0, K_TT * d + K_TR * a)
        across = rng.gauss(0, 0.5 * K_TT * d)
        heading = math.atan2(dy, dx) if d > 1e-6 else 0.0
        c, s = math.cos(heading), math.sin(heading)
        inc = (c * along - s * across, s * along + c * across,
               dth + BIAS_PER_M * d + rng.gauss(0, K_RR * a + K_RT * d))
        pose = compose(odo[-1], late) if late else odo[-1]
        late = None
        if rng.random() < P_STALL and i + 1 < len(poses):
            # a stale read-out: only the fraction u of this step is reported now, the
            # rest arrives with the next step (catch-up)
            u = rng.uniform(STALL_MIN, STALL_MAX)
            part = (inc[0] * u, inc[1] * u, inc[2] * u)
            late = rel(part, inc)
            inc = part
            stalls += 1
        odo.append(compose(pose, inc))
    return odo, stalls


def build_map(scans, maxr):
    xs = [s[1] for s in scans]
    ys = [s[2] for s in scans]
    reach = min(MAP_RANGE, maxr)
    x0 = min(xs) - reach - MARGIN
    y0 = min(ys) - reach - MARGIN
    x1 = max(xs) + reach + MARGIN
    y1 = max(ys) + reach + MARGIN
    hits = {}
    miss = {}
    for _, x, y, th, r in scans:
        n = len(r)
        cx0 = int((x - x0) / RES)
        cy0 = int((y - y0) / RES)
        for i, rr in enumerate(r):
            if rr >= maxr - 0.01 or rr <= 0.0:
                continue
            end = rr <= MAP_RANGE
            rr = min(rr, MAP_RANGE)
            b = th - math.pi / 2 + i * math.pi / (n - 1)
            ex = x + rr * math.cos(b)
            ey = y + rr * math.sin(b)
            cx1 = int((ex - x0) / RES)
            cy1 = int((ey - y0) / RES)
            # Bresenham from (cx0, cy0) to (cx1, cy1), the end cell excluded
            dx = abs(cx1 - cx0)
            dy = -abs(cy1 - cy0)
            sx = 1 if cx0 < cx1 else -1
            sy = 1 if cy0 < cy1 else -1
            err = dx + dy
            cx, cy = cx0, cy0
            while cx != cx1 or cy != cy1:
                k = (cx, cy)
                miss[k] = miss.get(k, 0) + 1
                e2 = 2 * err
                if e2 >= dy:
                    err += dy
                    cx += sx
                if e2 <= dx:
                    err += dx
                    cy += sy
            if end:
                k = (cx1, cy1)
                hits[k] = hits.get(k, 0) + 1
    # crop to the cells touched, plus the margin
    keys = list(miss.keys()) + list(hits.keys())
    mx0 = min(k[0] for k in keys) - int(MARGIN / RES)
    my0 = min(k[1] for k in keys) - int(MARGIN / RES)
    mx1 = max(k[0] for k in keys) + int(MARGIN / RES)
    my1 = max(k[1] for k in keys) + int(MARGIN / RES)
    w = mx1 - mx0 + 1
    h = my1 - my0 + 1
    img = bytearray([205]) * (w * h)
    for iy in range(h):
        row = (h - 1 - iy) * w  # PGM: first row at the top (largest y)
        for ix in range(w):
            k = (ix + mx0, iy + my0)
            nh = hits.get(k, 0)
            nm = miss.get(k, 0)
            if nh >= 2 and nh / (nh + nm) >= 0.25:
                img[row + ix] = 0
            elif nm >= 2:
                img[row + ix] = 254
    origin = (x0 + mx0 * RES, y0 + my0 * RES)
    return img, w, h, origin


def main():
    if len(sys.argv) < 2:
        print(__doc__)
        return 2
    src = sys.argv[1]
    names = sys.argv[2:] or ['intel', 'aces', 'fhw', 'seattle']
    for k, name in enumerate(names):
        scans, maxr = parse(f'{src}/{name}-corrected.log.gz')
        poses = [(s[1], s[2], s[3]) for s in scans]
        odo, stalls = odometry(poses, 1000 + k)
        img, w, h, origin = build_map(scans, maxr)
        with open(f'{name}.pgm', 'wb') as f:
            f.write(b'P5\n# %s: built by make_datasets.py from %s-corrected.log.gz\n%d %d\n255\n' % (name.encode(), name.encode(), w, h))
            f.write(bytes(img))
        with open(f'{name}.yaml', 'w') as f:
            f.write(f'# {name}: occupancy grid from the GMapping-corrected scans of {name}-corrected.log.gz\n'
                    f'# (acschaefer/ple, data from Radish; see README.md). Built by make_datasets.py.\n'
                    f'image: {name}.pgm\nresolution: {RES}\norigin: [{origin[0]:.3f}, {origin[1]:.3f}, 0.0]\n'
                    f'negate: 0\noccupied_thresh: 0.65\nfree_thresh: 0.196\n')
        with gzip.GzipFile(f'{name}.log.gz', 'wb', mtime=0) as g:
            out = [f'# {name}: {len(scans)} scans of {name}-corrected.log.gz (acschaefer/ple, from Radish), max range {maxr}\n'
                   f'# FLASER and ODOM poses: synthetic odometry (make_datasets.py error model, seed {1000 + k}, {stalls} stalls)\n'
                   f'# TRUEPOS x y theta odom_x odom_y odom_theta t host t: the GMapping-corrected pose (reference)\n'
                   f'PARAM flaser_max_range {maxr} nohost 0\n']
            for s, o in zip(scans, odo):
                t = s[0]
                rng = ' '.join(('%.3f' % v).rstrip('0').rstrip('.') for v in s[4])
                op = f'{o[0]:.4f} {o[1]:.4f} {o[2]:.5f}'
                out.append(f'ODOM {op} 0 0 0 {t:.6f} log {t:.6f}\n')
                out.append(f'TRUEPOS {s[1]:.4f} {s[2]:.4f} {s[3]:.5f} {op} {t:.6f} log {t:.6f}\n')
                out.append(f'FLASER {len(s[4])} {rng} {op} {op} {t:.6f} log {t:.6f}\n')
            g.write(''.join(out).encode())
        print(f'{name}: {len(scans)} scans, max range {maxr}, map {w} x {h} cells, origin {origin[0]:.2f} {origin[1]:.2f}, {stalls} stalls')
    return 0


if __name__ == '__main__':
    sys.exit(main())
