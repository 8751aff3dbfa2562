"""tests/bench/calculix_limit.py: the limit h -> 0 that the X-CAD benchmarks measure errors
against. On u(h) = u0 + c h^p it must return u0 and p (closed form); on the L-bracket runs kept
in tests/reference/calculix_limits.json it must give the figures of tests/bench/README.md; a kept set that does
not match a fresh run must be refused with the reason."""
import os
import sys
import unittest

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", "bench"))
import calculix_limit as cl  # noqa: E402


class Limit(unittest.TestCase):
    def test_power_law_gives_its_limit_and_order(self):
        for u0, c, p, sizes in [(-0.1114, 4.8e-4, 1.36, (1.0, 1.5, 2.0)), (5.0, -0.3, 2.0, (5.0, 8.0, 10.0)),
                                (-88.07, 7e-6, 0.9, (100.0, 150.0, 250.0))]:
            lim = cl.extrapolated_limit([(h, u0 + c * h ** p) for h in sizes])
            print("u0 %g, p %g: limit %.15g, order %.12f" % (u0, p, lim["u_probe"], lim["order"]))
            self.assertAlmostEqual(lim["order"], p, delta=1e-9)
            self.assertAlmostEqual(lim["u_probe"], u0, delta=1e-11 * abs(u0))

    def test_no_limit_from_a_non_monotone_or_short_sequence(self):
        self.assertIsNone(cl.extrapolated_limit([(1.0, 1.0), (2.0, 1.1)]))
        self.assertIsNone(cl.extrapolated_limit([(1.0, 1.0), (2.0, 1.1), (3.0, 1.05)]))

    def test_kept_bracket_runs_give_the_readme_limit(self):
        kept, why = cl.kept_runs("l_bracket", 1.5, -0.11056151982143436)
        self.assertIsNone(why)
        lim = cl.extrapolated_limit(kept)
        print("L-bracket: limit %.6f, order %.3f, h = 1.5 mm %.2f %% from it, order-1 spread %.2f %%"
              % (lim["u_probe"], lim["order"], 100 * abs(kept[1][1] - lim["u_probe"]) / abs(lim["u_probe"]),
                 100 * lim["uncertainty"]))
        # tests/bench/README.md, "XFEM against Gmsh + CalculiX" (the limit h -> 0): -0.111390 mm, order 1.36, 0.74 %, +-0.20 %
        self.assertAlmostEqual(lim["u_probe"], -0.111390, delta=5e-7)
        self.assertAlmostEqual(lim["order"], 1.36, delta=0.005)
        self.assertAlmostEqual(abs(-0.11056151982143436 - lim["u_probe"]) / abs(lim["u_probe"]), 0.0074, delta=5e-5)
        self.assertAlmostEqual(lim["uncertainty"], 0.0020, delta=5e-5)

    def test_kept_runs_that_do_not_match_are_refused(self):
        kept, why = cl.kept_runs("l_bracket", 1.5, -0.1106)
        self.assertIsNone(kept)
        self.assertIn("differs from this run's", why)
        kept, why = cl.kept_runs("l_bracket", 3.0, -0.109)
        self.assertIsNone(kept)
        self.assertIn("no kept run at h = 3", why)
        kept, why = cl.kept_runs("tube_turned", 5.0, -5.54)
        self.assertIn("no entry for tube_turned", why)


if __name__ == "__main__":
    unittest.main()
