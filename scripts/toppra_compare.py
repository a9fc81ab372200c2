#!/usr/bin/env python3
"""Compare lase's cycle time on a cornered path with the time-optimal bound from TOPP-RA.

One generated 2-axis path (a 24-corner zig-zag in a 200 x 200 mm field; every axis
v = 250 mm/s, a = 2000 mm/s^2, as the xy_table), three cases:

A. exact corners: the path must pass every corner exactly, so the time-optimal motion stops
   at each one. lase plans the 25 lines with junction deviation 0 (trapezoid profile);
   TOPP-RA plans each straight piece rest to rest (a straight line is its own smooth path).
   Both are bounded by per-axis velocity and acceleration only, so the ratio measures how close
   lase's profile is to time-optimal.
B. rounded corners: every corner is replaced by a tangent arc of radius R = 5 mm. TOPP-RA
   plans the exact geometric path (lines and arcs with their exact tangent and curvature), with
   the same per-axis limits, centripetal acceleration included. lase plans its own lowering of
   that path: the script hands `bench_plan --path` the lines and arcs, and lase turns each arc
   into chords with `motion::arc_points` (what `lase plan` does on a Cartesian machine) at the
   default arc tolerance 0.002 mm, then plans them with junction deviation 0.01 mm, trapezoid.
   The time is whatever lase's planner makes of its corners and chords, so a change to the
   corner handling shows here without touching the script.
C. S-curve: TOPP-RA has no jerk limit, so the fair comparison is lase's S-curve planner with a
   jerk so high it cannot bind (1e9 mm/s^3: the acceleration ramps to its limit in 2 us) on the
   moves of A and B, against the same bounds (ratio <= 1.01), and against lase's own trapezoid
   plan of the same moves (within 1e-4): the S-curve machinery costs nothing when jerk does
   not bind. The S-curve at the xy_table's real jerk (50 m/s^3) is printed for scale only.
D. S-curve where the jerk binds (50 m/s^3, the xy_table's): lase's plan of A's lines, stopping
   at each corner, against Ruckig's time-optimal jerk-limited motion per line, rest to rest,
   with the same per-axis v, a and j (phase-synchronized, so on the straight line): ratio
   >= 0.999 and <= 1.01.

TOPP-RA's grid is refined until its bound converges: the grid doubles until the bound moves by
at most 1.5e-4 (relative) between two grids. On B the bound falls with first-order error (each
doubling halves the change; the grid is uniform inside each piece and has every piece boundary,
where the curvature jumps), so the bound used is the Richardson limit 2 T(2n) - T(n). Every case
prints PASS or FAIL: lase must not beat the bound (ratio >= 1 - 1e-3, far above the bound's
remaining grid error) and must stay within 1 % of it (issue 13); the script exits 1 on a FAIL.

Output (2026-12-02, branch litfeed at c01fda7: lit corners blended with CURVE_SHARE 0.98; case B
was 1.0108, a FAIL, with main's 0.95 at b726d4e):

  TOPP-RA A, grid intervals -> bound: 100: 6.361092 s, 200: 6.361054 s; converged (last change 5.9e-06 <= 1.5e-04), extrapolated bound 6.361017 s
  TOPP-RA B, grid intervals -> bound: 6000: 5.189644 s, 12000: 5.179996 s, 24000: 5.172952 s, 48000: 5.170701 s, 96000: 5.169533 s, 192000: 5.168945 s; converged (last change 1.1e-04 <= 1.5e-04), extrapolated bound 5.168356 s
  PASS A exact corners (25 lines, stop at each corner): lase 6.361042 s, bound 6.361017 s, ratio 1.0000 (ratio >= 0.999 and <= 1.01)
  PASS B rounded corners (R 5.0 mm, 652 lase moves): lase 5.191557 s, bound 5.168356 s, ratio 1.0045 (ratio >= 0.999 and <= 1.01)
  PASS CA S-curve, j 1e+09 mm/s^3 (cannot bind): lase 6.361092 s, bound 6.361017 s, ratio 1.0000 (ratio >= 0.999 and <= 1.01)
  PASS CA S-curve vs lase's trapezoid plan: 6.361092 s vs 6.361042 s, +7.9e-06 (|.| <= 1e-4)
  PASS CB S-curve, j 1e+09 mm/s^3 (cannot bind): lase 5.191594 s, bound 5.168356 s, ratio 1.0045 (ratio >= 0.999 and <= 1.01)
  PASS CB S-curve vs lase's trapezoid plan: 5.191594 s vs 5.191557 s, +7.2e-06 (|.| <= 1e-4)
  PASS D S-curve, j 5e+04 mm/s^3, stop at each corner, vs Ruckig per line: lase 7.420316 s, bound 7.420316 s, ratio 1.0000 (ratio >= 0.999 and <= 1.01)
  info A S-curve, j 5e+04 mm/s^3: lase 7.420316 s, ratio 1.1665 (the jerk limit's cost; TOPP-RA has none)
  info B S-curve, j 5e+04 mm/s^3: lase 5.973354 s, ratio 1.1558 (the jerk limit's cost; TOPP-RA has none)

Every case passes. B is 0.45 % above the converged bound (it was 1.08 %, over the 1 % the issue
allows, with the share at 0.95). On chords of a curve lase caps the speed at sqrt(0.98 a_n r)
(Klipper's centripetal cap, r = R cos(phi/2) through the chord midpoints, scaled by CURVE_SHARE =
0.98 in runtime/src/planner/mod.rs) and keeps the rest of the budget for speed changes along the
curve, where TOPP-RA trades the two exactly at every point: on these R = 5 mm arcs the cap binds.
Before the cap (junction deviation alone) lase ran these arcs too fast: ratio 0.63.

lase's time comes from the example binary (`bench_plan --polyline` for A, `--path` for B),
built with `cargo build --release --example bench_plan -p lase-runtime` (the script builds it).

Usage: pip install toppra ruckig && python3 scripts/toppra_compare.py
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
from ruckig import InputParameter, Result, Ruckig, Synchronization, Trajectory

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
V, A = 250.0, 2000.0
RADIUS = 5.0
ARC_TOL = 0.002
# Relative change of TOPP-RA's bound between two grids at which it counts as converged: well
# below the 1e-3 by which lase may seem to beat it, and the 1e-2 it may exceed it by.
CONVERGED = 1.5e-4
# A jerk the S-curve cannot feel: the acceleration ramps to A in A / JERK_FREE = 2 us.
JERK_FREE = 1e9
JERK = 50_000.0


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


def write_pieces(pieces, f):
    """The filleted path as bench_plan's `--path` pieces: lase lowers the arcs itself."""
    f.write(f"start {float(pieces[0][1][0])!r} {float(pieces[0][1][1])!r}\n")
    for pc in pieces:
        if pc[0] == "line":
            f.write(f"line {float(pc[2][0])!r} {float(pc[2][1])!r}\n")
        else:
            _, c, r, a0, sweep = pc
            end = c + r * np.array([math.cos(a0 + sweep), math.sin(a0 + sweep)])
            f.write(f"arc {float(end[0])!r} {float(end[1])!r} {float(c[0])!r} {float(c[1])!r} "
                    f"{'ccw' if sweep > 0 else 'cw'}\n")


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


def piece_grid(starts, n):
    """About n grid intervals over the whole path, uniform inside each piece, every piece
    boundary (where the curvature jumps) a grid point: no sliver intervals, so the bound
    falls monotonically as the grid is refined."""
    h = starts[-1] / n
    return np.unique(np.concatenate([np.linspace(a, b, max(2, int(math.ceil((b - a) / h)) + 1))
                                     for a, b in zip(starts[:-1], starts[1:])]))


def toppra_duration(path, grid):
    """TOPP-RA's time-optimal duration along `path`, rest to rest, per-axis |v| <= V, |a| <= A."""
    vlim = np.array([[-V, V], [-V, V]])
    alim = np.array([[-A, A], [-A, A]])
    inst = algo.TOPPRA([constraint.JointVelocityConstraint(vlim),
                        constraint.JointAccelerationConstraint(alim)], path, gridpoints=grid,
                       parametrizer="ParametrizeConstAccel")
    traj = inst.compute_trajectory(0.0, 0.0)
    if traj is None:
        raise RuntimeError("TOPP-RA found no parameterization")
    return traj.duration


def converged(label, duration_at, n0, n_max):
    """Doubles the grid from n0 until the bound moves by at most CONVERGED (relative) between
    two grids; prints the sequence. TOPP-RA's bound falls with first-order error here (each
    doubling halves the change), so the limit is 2 T(2n) - T(n) (Richardson), and what is left
    of the error after the last grid is about the last change."""
    n, prev, seq = n0, None, []
    while True:
        t = duration_at(n)
        seq.append(f"{n}: {t:.6f} s")
        if prev is not None and abs(prev - t) <= CONVERGED * t:
            bound = 2.0 * t - prev
            break
        if n >= n_max:
            raise RuntimeError(f"{label}: TOPP-RA bound not converged: {', '.join(seq)}")
        n, prev = 2 * n, t
    print(f"  TOPP-RA {label}, grid intervals -> bound: {', '.join(seq)}; converged "
          f"(last change {abs(prev - t) / t:.1e} <= {CONVERGED:.1e}), extrapolated bound "
          f"{bound:.6f} s")
    return bound


def toppra_exact_bound(pieces):
    path = ExactPath(pieces)
    return converged("B", lambda n: toppra_duration(path, piece_grid(path.starts, n)),
                     6000, 400_000)


def toppra_lines_bound(pts):
    """Sum over the straight pieces, each rest to rest (a straight line is its own smooth
    path: linear in s)."""
    paths = []
    for p, q in zip(pts[:-1], pts[1:]):
        s = float(np.linalg.norm(q - p))
        paths.append(ta.SplineInterpolator(np.array([0.0, s]), np.array([p, q])))
    return converged("A", lambda n: sum(toppra_duration(pa, np.linspace(0.0, pa.path_interval[1],
                                                                       n + 1))
                                        for pa in paths), 100, 100_000)


def lase_time(flag, write, jd, profile="trapezoid", jerk=None):
    """lase's planned cycle time (bench_plan, release build) for the input `write` makes."""
    exe = os.path.join(os.environ.get("CARGO_TARGET_DIR", os.path.join(ROOT, "target")),
                       "release", "examples", "bench_plan")
    with tempfile.NamedTemporaryFile("w", suffix=".txt", delete=False) as f:
        write(f)
        name = f.name
    args = [exe, flag, name, "--v", str(V), "--a", str(A), "--jd", str(jd), "--profile", profile,
            "--arc-tol", str(ARC_TOL)]
    if jerk is not None:
        args += ["--j", str(jerk)]
    try:
        out = subprocess.run(args, check=True, capture_output=True, text=True).stdout
    finally:
        os.unlink(name)
    res = json.loads(out)
    return res["duration_s"], res.get("moves", res["segments"])


def ruckig_rest_to_rest(pts, jerk):
    """Sum over the straight pieces of Ruckig's time-optimal jerk-limited motion, rest to rest,
    per-axis v, a and j; phase synchronization keeps both axes on the straight line."""
    total = 0.0
    for p, q in zip(pts[:-1], pts[1:]):
        inp = InputParameter(2)
        inp.current_position, inp.target_position = list(p), list(q)
        inp.current_velocity = inp.current_acceleration = [0.0, 0.0]
        inp.target_velocity = inp.target_acceleration = [0.0, 0.0]
        inp.max_velocity, inp.max_acceleration, inp.max_jerk = [V] * 2, [A] * 2, [jerk] * 2
        inp.synchronization = Synchronization.Phase
        traj = Trajectory(2)
        if Ruckig(2).calculate(inp, traj) != Result.Working:
            raise RuntimeError(f"Ruckig found no trajectory from {p} to {q}")
        total += traj.duration
    return total


def write_points(points):
    return lambda f: f.writelines(f"{float(p[0])!r},{float(p[1])!r}\n" for p in points)


def verdict(name, t_lase, bound, upper):
    """PASS when lase does not beat the bound (ratio >= 1 - 1e-3, the bound's own grid error
    is far below that) and, where the issue asks, stays within `upper` of it."""
    ratio = t_lase / bound
    ok = ratio >= 1.0 - 1e-3 and (upper is None or ratio <= upper)
    want = "ratio >= 0.999" + (f" and <= {upper}" if upper is not None else "")
    print(f"{'PASS' if ok else 'FAIL'} {name}: lase {t_lase:.6f} s, bound {bound:.6f} s, "
          f"ratio {ratio:.4f} ({want})")
    return ok


def main():
    subprocess.run(["cargo", "build", "--release", "-q", "-p", "lase-runtime", "--example",
                    "bench_plan"], cwd=ROOT, check=True)
    pts = corners()
    pieces = fillet(pts, RADIUS)
    bound_a = toppra_lines_bound(pts)
    bound_b = toppra_exact_bound(pieces)
    ok = True
    # A: exact corners, junction deviation 0.
    t_a, _ = lase_time("--polyline", write_points(pts), 0.0)
    ok &= verdict(f"A exact corners ({len(pts) - 1} lines, stop at each corner)", t_a, bound_a,
                  1.01)
    # B: rounded corners, the arcs lowered by lase.
    t_b, moves = lase_time("--path", lambda f: write_pieces(pieces, f), 0.01)
    ok &= verdict(f"B rounded corners (R {RADIUS} mm, {moves} lase moves)", t_b, bound_b, 1.01)
    # C: the S-curve planner with a jerk that cannot bind, against the bound, and against
    # lase's own trapezoid plan of the same moves (the S-curve machinery's cost alone, apart
    # from how lase takes corners).
    for name, flag, write, jd, bound, t_trap in [
            ("A", "--polyline", write_points(pts), 0.0, bound_a, t_a),
            ("B", "--path", lambda f: write_pieces(pieces, f), 0.01, bound_b, t_b)]:
        t, _ = lase_time(flag, write, jd, "scurve", JERK_FREE)
        ok &= verdict(f"C{name} S-curve, j {JERK_FREE:.0e} mm/s^3 (cannot bind)", t, bound, 1.01)
        cost = t / t_trap - 1.0
        good = abs(cost) <= 1e-4
        ok &= good
        print(f"{'PASS' if good else 'FAIL'} C{name} S-curve vs lase's trapezoid plan: "
              f"{t:.6f} s vs {t_trap:.6f} s, {cost:+.1e} (|.| <= 1e-4)")
    # D: where the jerk binds, lase's S-curve stop to stop on A's lines against Ruckig.
    t, _ = lase_time("--polyline", write_points(pts), 0.0, "scurve", JERK)
    ok &= verdict(f"D S-curve, j {JERK:.0e} mm/s^3, stop at each corner, vs Ruckig per line", t,
                  ruckig_rest_to_rest(pts, JERK), 1.01)
    # For scale, not asserted: the S-curve at the xy_table's own jerk, which TOPP-RA ignores.
    for name, flag, write, jd, bound in [
            ("A", "--polyline", write_points(pts), 0.0, bound_a),
            ("B", "--path", lambda f: write_pieces(pieces, f), 0.01, bound_b)]:
        t, _ = lase_time(flag, write, jd, "scurve", JERK)
        print(f"info {name} S-curve, j {JERK:.0e} mm/s^3: lase {t:.6f} s, ratio "
              f"{t / bound:.4f} (the jerk limit's cost; TOPP-RA has none)")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
