"""The ring of samples/parts/ring.step (r = 20..30 mm, 10 mm high) compressed axially by a
10 MPa traction on its top, bottom clamped, simulated at eight rotations of the part inside the
fixed grid (cf. thesis Fig. 6.14). The axial stress along a radial line at mid-height must not
depend on how the grid cuts the part, and its mean must carry the load: mean σ_zz = −p."""
import json
import math
import os
import sys
import unittest

sys.path.insert(0, os.environ.get("PARAFAB_MODULE_DIR", "build/workbench/entry"))
import parafab  # noqa: E402

RING = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "samples", "parts", "ring.step")
P = 10.0


class RingRotations(unittest.TestCase):
    def test_axial_stress_is_independent_of_the_grid_orientation(self):
        faces = parafab.inspect_part(RING)["faces"]
        bottom = [f["index"] for f in faces if f["type"] == "plane" and abs(f["parameters"]["p"][2]) < 1e-9]
        top = [f["index"] for f in faces if f["type"] == "plane" and abs(f["parameters"]["p"][2] - 10) < 1e-9]
        self.assertEqual((len(bottom), len(top)), (1, 1))
        radii = [21 + 8 * k / 8 for k in range(9)]
        spreads = []
        for cells in (12, 24):
            mean, spread = self.rotations(cells, bottom[0], top[0], radii)
            print("%d cells: mean sigma_zz per rotation %s, largest difference between rotations %.3f MPa"
                  % (cells, ["%.3f" % m for m in mean], spread))
            for m in mean:
                self.assertAlmostEqual(m, -P, delta=0.05 * P)  # the load is carried
            spreads.append(spread)
        self.assertLess(spreads[1], 0.6 * spreads[0])  # converging for every rotation
        self.assertLess(spreads[1], 0.07 * P)

    def rotations(self, cells, bottom, top, radii):
        profiles = []
        for k in range(8):
            deg = 45.0 * k / 8 + 3.7  # never aligned with the grid
            a = math.radians(deg)
            job = {"material": {"E": 210000, "nu": 0.3}, "element": "hex8", "grid": {"cells": cells},
                   "supports": [{"face": bottom}], "loads": [{"face": top, "traction": [0, 0, -P]}],
                   "rotate": {"axis": [0, 0, 1], "center": [0, 0, 0], "degrees": deg},
                   "probes": [[r * math.cos(a), r * math.sin(a), 5.0] for r in radii]}
            r = parafab.simulate(RING, job)
            profiles.append([p["stress"][2] for p in r["probes"]])
        mean = [sum(p) / len(p) for p in profiles]
        spread = max(max(abs(a - b) for a, b in zip(p, profiles[0])) for p in profiles)
        return mean, spread


if __name__ == "__main__":
    unittest.main()
