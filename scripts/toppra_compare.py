#!/usr/bin/env python3
"""Compare lase's cycle time on a cornered path with the time-optimal bound from TOPP-RA.

Two cases on one generated 2-axis path (a 24-corner zig-zag in a 200 x 200 mm field; every
axis v = 250 mm/s, a = 2000 mm/s^2, as the xy_table):

A. exact corners: the path must pass every corner exactly, so the time-optimal motion stops
   at each one. lase plans with junction deviation 0 (trapezoid profile); TOPP-RA plans each
   straight piece rest to rest (a straight line is its own smooth path). Both are bounded by
   per-axis velocity and acceleration only, so the ratio measures how close lase's profile is
   to time-optimal.
B. rounded corners: every corner is replaced by a tangent arc of radius R = 5 mm. TOPP-RA
   plans the exact geometric path (lines and arcs with their exact tangent and curvature, grid
   of 6000 points plus every piece boundary), with the same per-axis limits, centripetal
   acceleration included. lase
   plans what its lowering would send: the lines whole, the arcs as chords within 0.002 mm,
   junction deviation 0.01 mm, trapezoid. lase bounds the chords' centripetal acceleration
   with Klipper's cap (a circle through the chord midpoints, v^2 <= a_n r) and keeps 95 % of
   the limit for it on chords of a curve, the rest for speed changes along them, so it should
   never beat the time-optimal bound (ratio >= 1). Before the cap (junction deviation alone)
   lase ran these arcs too fast: ratio 0.63.

lase's time comes from the end-to-end example binary (`bench_plan --polyline`), built with
`cargo build --release --example bench_plan -p lase-runtime` (the script builds it).

Usage: pip install toppra && python3 scripts/toppra_compare.py
"""

import json
import math
import os
import random
import subprocess
import sys
import tempfile

import numpy as np
import toppra as ta
import toppra.algorithm as algo
import toppra.constraint as constraint

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
V, A = 250.0, 2000.0
RADIUS = 5.0
ARC_TOL = 0.002


def corners(n=24, seed=7):
    """A zig-zag: lengths 20-60 mm, turns of 40-140 degrees alternating left and right."""
    rnd = random.Random(seed)
    p = np.array([-80.0, -80.0])
    heading = math.radians(30.0)
    pts = [p.copy()]
    for k in range(n + 1):
        length = rnd.uniform(20.0, 60.0)
        q = p + length * np.array([math.cos(heading), math.sin(heading)])
        if np.any(np.abs(q) > 95.0):
            heading += math.pi * 0.75
            q = p + length * np.array([math.cos(heading), math.sin(heading)])
            q = np.clip(q, -95.0, 95.0)
        pts.append(q)
        p = q
        turn = math.radians(rnd.uniform(40.0, 140.0))
        heading += turn if k % 2 == 0 else -turn
    return np.array(pts)


def fillet(pts, r):
    """Lines and tangent arcs: [(kind, data)] with ("line", p0, p1) and ("arc", c, a0, sweep)."""
    pieces = []
    start = pts[0]
    for i in range(1, len(pts) - 1):
        a, b, c = pts[i - 1], pts[i], pts[i + 1]
        u = (b - a) / np.linalg.norm(b - a)
        w = (c - b) / np.linalg.norm(c - b)
        turn = math.atan2(u[0] * w[1] - u[1] * w[0], float(u @ w))
        t = r * math.tan(abs(turn) / 2.0)
        t = min(t, 0.45 * np.linalg.norm(b - a), 0.45 * np.linalg.norm(c - b))
        rr = t / math.tan(abs(turn) / 2.0)
        p_in, p_out = b - t * u, b + t * w
        n = np.array([-u[1], u[0]]) * (1.0 if turn > 0 else -1.0)
        center = p_in + rr * n
        pieces.append(("line", start, p_in))
        a0 = math.atan2(p_in[1] - center[1], p_in[0] - center[0])
        pieces.append(("arc", center, rr, a0, turn))
        start = p_out
    pieces.append(("line", start, pts[-1]))
    return pieces


def lase_chords(pieces):
    """What lase's lowering sends: lines whole, arcs as chords with sagitta <= ARC_TOL."""
    out = [pieces[0][1]]
    for pc in pieces:
        if pc[0] == "line":
            out.append(pc[2])
        else:
            _, c, r, a0, sweep = pc
            max_step = 2.0 * math.acos(1.0 - ARC_TOL / r) if r > ARC_TOL else math.pi / 2
            n = max(1, int(math.ceil(abs(sweep) / max_step)))
            out += [c + r * np.array([math.cos(a0 + sweep * k / n), math.sin(a0 + sweep * k / n)])
                    for k in range(1, n + 1)]
    return np.array(out)


class ExactPath(ta.interpolator.AbstractGeometricPath):
    """Lines and arcs parameterized by arc length, with exact first and second derivatives
    (unit tangent, curvature normal), so TOPP-RA sees the true geometry and its curvature."""

    def __init__(self, pieces):
        self.pieces = pieces
        lengths = [np.linalg.norm(p[2] - p[1]) if p[0] == "line" else abs(p[4]) * p[2]
                   for p in pieces]
        self.starts = np.concatenate([[0.0], np.cumsum(lengths)])

    @property
    def dof(self):
        return 2

    @property
    def path_interval(self):
        return np.array([0.0, self.starts[-1]])

    @property
    def waypoints(self):
        return None

    def __call__(self, ss, order=0):
        ss = np.atleast_1d(ss)
        out = np.zeros((len(ss), 2))
        for k, s in enumerate(ss):
            i = min(max(np.searchsorted(self.starts, s, side="right") - 1, 0), len(self.pieces) - 1)
            pc, u = self.pieces[i], s - self.starts[i]
            if pc[0] == "line":
                d = (pc[2] - pc[1]) / np.linalg.norm(pc[2] - pc[1])
                out[k] = [pc[1] + u * d, d, np.zeros(2)][order]
            else:
                _, c, r, a0, sweep = pc
                sg = 1.0 if sweep > 0 else -1.0
                a = a0 + sg * u / r
                p = c + r * np.array([math.cos(a), math.sin(a)])
                t = sg * np.array([-math.sin(a), math.cos(a)])
                n = -np.array([math.cos(a), math.sin(a)]) / r
                out[k] = [p, t, n][order]
        return out


def toppra_exact(pieces, gridpoints):
    path = ExactPath(pieces)
    vlim = np.array([[-V, V], [-V, V]])
    alim = np.array([[-A, A], [-A, A]])
    grid = np.linspace(0.0, path.path_interval[1], gridpoints)
    # Include every piece boundary, where the curvature jumps.
    grid = np.unique(np.concatenate([grid, path.starts]))
    inst = algo.TOPPRA([constraint.JointVelocityConstraint(vlim),
                        constraint.JointAccelerationConstraint(alim)], path, gridpoints=grid,
                       parametrizer="ParametrizeConstAccel")
    traj = inst.compute_trajectory(0.0, 0.0)
    if traj is None:
        raise RuntimeError("TOPP-RA found no parameterization")
    return traj.duration


def toppra_time(points, gridpoints=2000):
    """Time-optimal duration along the path through `points` (arc-length parameterized
    cubic spline), rest to rest, per-axis |v| <= V and |a| <= A."""
    seg = np.linalg.norm(np.diff(points, axis=0), axis=1)
    keep = np.concatenate([[True], seg > 1e-9])
    points = points[keep]
    s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(points, axis=0), axis=1))])
    if len(points) == 2:
        # A straight line: linear in s (a two-point spline is exactly that).
        path = ta.SplineInterpolator(s, points)
    else:
        path = ta.SplineInterpolator(s, points, bc_type="natural")
    vlim = np.array([[-V, V], [-V, V]])
    alim = np.array([[-A, A], [-A, A]])
    pc_vel = constraint.JointVelocityConstraint(vlim)
    pc_acc = constraint.JointAccelerationConstraint(alim)
    grid = np.linspace(0.0, s[-1], gridpoints)
    inst = algo.TOPPRA([pc_vel, pc_acc], path, gridpoints=grid, parametrizer="ParametrizeConstAccel")
    traj = inst.compute_trajectory(0.0, 0.0)
    if traj is None:
        raise RuntimeError("TOPP-RA found no parameterization")
    return traj.duration


def lase_time(points, jd):
    exe = os.path.join(os.environ.get("CARGO_TARGET_DIR", os.path.join(ROOT, "target")),
                       "release", "examples", "bench_plan")
    with tempfile.NamedTemporaryFile("w", suffix=".csv", delete=False) as f:
        for p in points:
            f.write(f"{float(p[0])!r},{float(p[1])!r}\n")
        name = f.name
    try:
        out = subprocess.run([exe, "--polyline", name, "--v", str(V), "--a", str(A),
                              "--jd", str(jd), "--profile", "trapezoid"],
                             check=True, capture_output=True, text=True).stdout
    finally:
        os.unlink(name)
    return json.loads(out)["duration_s"]


def main():
    subprocess.run(["cargo", "build", "--release", "-q", "-p", "lase-runtime", "--example",
                    "bench_plan"], cwd=ROOT, check=True)
    pts = corners()
    # A: exact corners.
    t_lase = lase_time(pts, 0.0)
    t_opt = sum(toppra_time(np.array([pts[i], pts[i + 1]]), 400) for i in range(len(pts) - 1))
    print(f"A exact corners ({len(pts) - 1} lines, stop at each corner): lase {t_lase:.6f} s, "
          f"TOPP-RA {t_opt:.6f} s, ratio {t_lase / t_opt:.4f}")
    # B: rounded corners.
    pieces = fillet(pts, RADIUS)
    t_opt_b = toppra_exact(pieces, 6000)
    chords = lase_chords(pieces)
    t_lase_b = lase_time(chords, 0.01)
    print(f"B rounded corners (R {RADIUS} mm, {len(chords) - 1} lase moves): lase {t_lase_b:.6f} s, "
          f"TOPP-RA {t_opt_b:.6f} s, ratio {t_lase_b / t_opt_b:.4f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
