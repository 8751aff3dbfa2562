"""Where Nitsche's method fails (thesis Eq. 6.22 and its inset, §6.4.3), on the ring of thesis
Fig. 6.14 compressed by a prescribed displacement: the top face (z = 10) is pushed down
5 µm, the bottom clamped, ν = 0.3, the part turned 3.7° inside the grid. The axial stress along
a radial line at mid-height is compared with a 32-cell run at the default β.

- β too small (≤ 1): the stiffness matrix is not positive definite; the result says so and the
  stress is far off.
- β in the valid range (10): the closest to the reference.
- β too large (10⁴–10⁶): stable (no blow-up, the solution tends to the penalty limit), but the
  elements cut by the clamped faces stiffen (locking): the error grows and then stays."""
import math
import os
import sys
import unittest

sys.path.insert(0, os.environ.get("PARAFAB_MODULE_DIR", "build/workbench/entry"))
import parafab  # noqa: E402

RING = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "samples", "parts", "ring.step")
DEG = 3.7
RADII = [21 + k for k in range(9)]


def faces():
    fs = parafab.inspect_part(RING)["faces"]
    bottom = [f["index"] for f in fs if f["type"] == "plane" and abs(f["parameters"]["p"][2]) < 1e-9]
    top = [f["index"] for f in fs if f["type"] == "plane" and abs(f["parameters"]["p"][2] - 10) < 1e-9]
    return bottom[0], top[0]


def profile(cells, beta=None):
    bottom, top = faces()
    a = math.radians(DEG)
    job = {"material": {"E": 210000, "nu": 0.3}, "grid": {"cells": cells},
           "supports": [{"face": bottom}, {"face": top, "displacement": [0, 0, -0.005]}],
           "rotate": {"axis": [0, 0, 1], "center": [0, 0, 0], "degrees": DEG},
           "probes": [[r * math.cos(a), r * math.sin(a), 5.0] for r in RADII]}
    if beta is not None:
        job["nitsche_beta"] = beta
    r = parafab.simulate(RING, job)
    return [p["stress"][2] for p in r["probes"]], r["message"]


class RingNitscheBeta(unittest.TestCase):
    def test_beta_too_small_is_unstable_and_too_large_locks(self):
        ref, _ = profile(32)
        scale = abs(sum(ref) / len(ref))
        err, msg = {}, {}
        for beta in (0.1, 1, 10, 100, 1e4, 1e6):
            s, msg[beta] = profile(12, beta)
            err[beta] = max(abs(x - y) for x, y in zip(s, ref)) / scale
            print("beta %8g: largest stress error %.3f of the mean %s" % (beta, err[beta], msg[beta][:40]))
        for beta in (0.1, 1):
            self.assertIn("not positive definite", msg[beta])
            self.assertGreater(err[beta], 0.3)
        for beta in (10, 100, 1e4, 1e6):
            self.assertEqual(msg[beta], "")
        self.assertLess(err[10], 0.15)
        self.assertGreater(err[1e4], 1.2 * err[10])            # locking
        self.assertAlmostEqual(err[1e6], err[1e4], delta=0.01)  # the penalty limit: stable, not blowing up


if __name__ == "__main__":
    unittest.main()
