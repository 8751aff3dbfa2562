"""160 shape parameters at once (issue 12, thesis §6.6.1 and Table 6.1, "topology optimization":
a grid of 20 x 8 square holes whose sides are the design variables). samples/parts/bridge_holes.step
is a plate 200 x 80 x 2.5 mm with square holes of side 5.5 on a 10 mm pitch; both ends clamped,
the deck loaded, volume <= start. Each hole's +x wall offset is its design variable and its other
three walls follow as that wall turned by 90°, 180°, 270° about the hole's axis (`rotations`), the
job tests/bench/bench_optimize_bridge.py builds (here on a coarser grid and for few iterations).

Checked on the written STEP by the part inspector (its own face model of the new file), not on
the optimizer's numbers:
- every hole is still a square about its own centre;
- OCCT's volume of the written part equals the closed form 2.5 (200 · 80 − Σ l²) of the
  inspected sides, and is at most the start's;
- a fresh simulation on another grid finds the written part stiffer;
- the loads and supports are symmetric about x = 100 and so is the result.
And the gradient of one hole's side, through the projection that moves its four walls, against
central differences of the whole pipeline (each side a fresh run from "start")."""
import os
import shutil
import sys
import tempfile
import unittest

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.environ.get("PARAFAB_MODULE_DIR", "build/workbench/entry"))
sys.path.insert(0, os.path.join(HERE, "..", "bench"))
import parafab  # noqa: E402
import bench_optimize_bridge as bridge  # noqa: E402  (the benchmark's job, so both test one thing)

CELLS = 40  # 2 x 2 elements per hole pitch: every hole wall cuts cells (walls at 2.25, 7.75 of 10)


def holes_of(path):
    """(side along x, side along y, centre x, centre y) of each hole of the part in `path`, in
    bridge.centres() order, from the inspected planes of its walls, each read where it crosses
    the line through the hole's nominal centre (mid-thickness), and the largest in-plane tilt of
    a wall's normal [rad] (a wall tilted by t, read at the plane's origin 75 mm away, would seem
    to move by 75 t)."""
    walls, tilt = {}, 0.0
    for f in parafab.inspect_part(path)["faces"]:
        if f["type"] != "plane":
            continue
        pr = f["parameters"]
        p, xd, n = np.array(pr["p"]), np.array(pr["x"]), np.array(pr["n"])
        yd = np.cross(n, xd)
        pts = np.array([p + uv[0] * xd + uv[1] * yd for loop in f["loops"] for uv in loop["uv"]])
        lo, hi = pts.min(axis=0), pts.max(axis=0)
        i, j = int(lo[0] // bridge.PITCH), int(lo[1] // bridge.PITCH)
        # a hole wall lies inside one pitch cell, away from its borders; outer faces do not
        if (hi[0] - i * bridge.PITCH < bridge.PITCH - 1e-6 and hi[1] - j * bridge.PITCH < bridge.PITCH - 1e-6
                and min(lo[0] - i * bridge.PITCH, lo[1] - j * bridge.PITCH) > 1e-6 and abs(n[2]) < 1e-12):
            axis = 0 if abs(n[0]) > 0.5 else 1
            centre = np.array([(i + 0.5) * bridge.PITCH, (j + 0.5) * bridge.PITCH, bridge.THICK / 2])
            other = centre.copy()
            other[axis] = 0
            walls.setdefault((i, j), [[], []])[axis].append(float((n @ p - n @ other) / n[axis]))
            tilt = max(tilt, abs(n[1 - axis]))
    out = []
    for cx, cy in bridge.centres():
        xs, ys = walls[(int(cx // bridge.PITCH), int(cy // bridge.PITCH))]
        assert len(xs) == 2 and len(ys) == 2, (cx, cy, xs, ys)
        out.append((abs(xs[1] - xs[0]), abs(ys[1] - ys[0]), sum(xs) / 2, sum(ys) / 2))
    return out, tilt


def compliance(path, cells):
    return -2 * parafab.simulate(path, dict(bridge.SIM, grid={"cells": cells}))["potential"]


class OptimizeBridge(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.dir = tempfile.mkdtemp()
        cls.job = bridge.job(cells=CELLS, iterations=2)

    @classmethod
    def tearDownClass(cls):
        shutil.rmtree(cls.dir)

    def test_160_sides_keep_the_holes_square_and_the_volume_bound(self):
        h = parafab.optimize(bridge.BRIDGE, self.job, out_dir=os.path.join(self.dir, "run"))
        self.assertEqual(len(h["parameters"]), 160)
        holes, tilt = holes_of(h["optimized_step"])
        start, _ = holes_of(bridge.BRIDGE)
        sides = np.array([sx for sx, _, _, _ in holes])
        moved = np.abs(sides - bridge.SIDE)
        square = max(abs(sx - sy) for sx, sy, _, _ in holes)
        centre = max(np.hypot(x - x0, y - y0) for (_, _, x, y), (_, _, x0, y0) in zip(holes, start))
        v0, v1 = parafab.inspect_part(bridge.BRIDGE)["volume"], parafab.inspect_part(h["optimized_step"])["volume"]
        closed = bridge.THICK * (200 * 80 - float(np.sum(sides ** 2)))
        grid = sides.reshape(bridge.NX, bridge.NY)
        asym = float(np.max(np.abs(grid - grid[::-1, :])))
        c0, c1 = compliance(bridge.BRIDGE, 60), compliance(h["optimized_step"], 60)
        print("bridge %d cells, %d iterations, %d evaluations: C %.6g -> %.6g (optimizer), fresh 60 cells %.6g -> "
              "%.6g; sides %.4f ... %.4f (moved > 1e-3 mm: %d, > 1e-2 mm: %d); not square by %.2e mm, centres "
              "moved %.2e mm, walls tilted %.2e rad; V/V0 %.9f, OCCT vs closed form %.2e; asymmetry %.2e mm; %.1f s"
              % (CELLS, len(h["iterations"]) - 1, h["evaluations"], h["initial_objective"], h["final_objective"],
                 c0, c1, sides.min(), sides.max(), int(np.sum(moved > 1e-3)), int(np.sum(moved > 0.01)), square,
                 centre, tilt, v1 / v0, abs(v1 / closed - 1), asym, h["seconds"]))
        # Measured (2026-12-01 22:20, the job's multiplier estimate): 3 iterates, 3 evaluations;
        # C 0.948229 -> 0.729983 on the optimizer's grid, 0.904956 -> 0.763461 fresh on 60 cells;
        # all 160 sides moved by more than 1e-2 mm (1.5012 ... 7.6465; from a multiplier of 0 the
        # penalty kept them within 0.014 mm); squares to 9e-12 mm, centres 8.6e-12 mm (read at the
        # holes); OCCT's volume 7e-14 from the closed form, V/V0 0.9576.
        # The walls' normals tilt by 3.2e-7 rad: the projection's nearest model trades that tilt
        # for its followers' offsets (weights 1e-4 on offsets, L^2 on normal components; a wall's
        # offset changes with its normal by the hole centre's distance from the origin). Read at
        # the planes' origins the centres seemed to move by 6.8e-5 mm.
        # Mirrored holes agree to 2.7e-7 mm (7e-8 of the sides' change of up to 4 mm; 3.6e-10
        # when the sides moved 0.014 mm): the 40-cell grid is symmetric about x = 100 only up to
        # its plane shifts off face extremes.
        self.assertEqual(h["invalid_models"], 0)
        self.assertEqual(int(np.sum(moved > 1e-2)), 160)
        self.assertLess(square, 1e-10)
        self.assertLess(centre, 1e-10)
        self.assertLess(tilt, 1e-6)
        self.assertLess(abs(v1 / closed - 1), 1e-12)
        self.assertLessEqual(v1 / v0, 1 + 1e-7)
        self.assertLess(c1, 0.9 * c0)
        self.assertLess(h["final_objective"], 0.8 * h["initial_objective"])
        self.assertLess(asym, 1e-6)

    def test_a_sides_gradient_matches_central_differences(self):
        """Hole (9, 7), under the deck next to the middle, on 20 cells (its walls at 2.25 and 7.75
        of each 10 mm cell: all four cut cells): the exact gradient (history gradient_initial) against Richardson-extrapolated central
        differences (H = 0.02 and 0.01 mm of its +x wall offset) of fresh runs from "start"."""
        k = 9 * bridge.NY + 7
        job = dict(self.job, max_iterations=0, grid={"cells": 20})  # one element per hole pitch: cheaper
        h = parafab.optimize(bridge.BRIDGE, job)
        x0 = np.array([p["initial"] for p in h["parameters"]])
        g = h["parameters"][k]["gradient_initial"]

        def at(step):
            x = x0.copy()
            x[k] += step
            return parafab.optimize(bridge.BRIDGE, dict(job, start=list(x)))["initial_objective"]

        d = {H: (at(H) - at(-H)) / (2 * H) for H in (0.02, 0.01)}
        fd = (4 * d[0.01] - d[0.02]) / 3
        print("hole (9, 7): gradient %.10g, central differences %.10g (H 0.02) %.10g (H 0.01), Richardson %.10g, "
              "relative %.2e" % (g, d[0.02], d[0.01], fd, abs(g / fd - 1)))
        # Measured 2.6e-10 (1.5e-10 on 40 cells); plain central differences at H = 0.01 are 7e-6 off.
        self.assertGreater(abs(g), 1e-4)
        self.assertLess(abs(g / fd - 1), 2e-9)


if __name__ == "__main__":
    unittest.main()
