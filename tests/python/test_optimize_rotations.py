"""Rotational symmetry of `parafab optimize` (issue 12: "mirror or rotational symmetry"): job field
"rotations": [{"faces": [f0, f1, ...], "axis": {"point", "direction"}, "degrees": θ}], face k+1 the
copy of face k turned by θ. The flange (samples/parts/flange.step: disc r 50, 8 thick, bore r 12,
six bolt holes r 5 on the circle of radius 32) is made lighter with one hole's radius and axis
point as the design entries. Without the pattern only that hole grows; with it all six follow.
Checked on the written STEP by the part inspector (its own face model of the new file): radii,
centres turned by 60° about z, and the mass against the closed form ρ·8·π(50² − 12² − Σ r²).
Bad entries are errors naming the entry."""
import math
import os
import sys
import tempfile
import unittest

sys.path.insert(0, os.environ.get("PARAFAB_MODULE_DIR", "build/workbench/entry"))
import parafab  # noqa: E402
from optimize_cli import optimize_cli_error  # noqa: E402

FLANGE = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "samples", "parts", "flange.step")


def on_hole(k):
    """A point on the wall of bolt hole k (centre at 60k° on the circle of radius 32, radius 5)."""
    t = math.radians(60 * k)
    return [37 * math.cos(t), 37 * math.sin(t), 4.0]


PATTERN = {"faces": [on_hole(k) for k in range(6)], "axis": {"point": [0, 0, 0], "direction": [0, 0, 1]},
           "degrees": 60}
JOB = {"objective": {"type": "mass", "density": 1.0},
       "parameters": [{"point": on_hole(0), "parameter": p} for p in ("radius", "axis point x", "axis point y")],
       "max_iterations": 10, "bound": 0.3}


def holes_of(path):
    """(angle, centre xy, radius) of the bolt holes of the part in `path`, by angle from +x."""
    holes = []
    for f in parafab.inspect_part(path)["faces"]:
        c, r = f["parameters"].get("c"), f["parameters"].get("r")
        if f["type"] == "cylinder" and math.hypot(c[0], c[1]) > 20:
            holes.append((math.atan2(c[1], c[0]) % (2 * math.pi), c[:2], r))
    return sorted(holes)


def closed_form_mass(holes):
    return 8 * math.pi * (50 ** 2 - 12 ** 2 - sum(r * r for _, _, r in holes))


class OptimizeRotations(unittest.TestCase):
    def test_the_pattern_follows_the_designed_hole(self):
        free = parafab.optimize(FLANGE, JOB, out_dir=tempfile.mkdtemp())
        held = parafab.optimize(FLANGE, dict(JOB, rotations=[PATTERN]), out_dir=tempfile.mkdtemp())
        free_holes, held_holes = holes_of(free["optimized_step"]), holes_of(held["optimized_step"])
        print("free: mass %.2f -> %.2f, radii %s" % (free["initial_objective"], free["final_objective"],
                                                    [round(r, 6) for _, _, r in free_holes]))
        print("pattern: mass %.2f -> %.2f, radii %s" % (held["initial_objective"], held["final_objective"],
                                                       [round(r, 6) for _, _, r in held_holes]))
        self.assertEqual(len(free_holes), 6)
        self.assertEqual(len(held_holes), 6)
        # Alone, hole 0 grows to its bound (5 · 1.3) and the others keep r = 5.
        self.assertAlmostEqual(free_holes[0][2], 6.5, delta=1e-3)
        for _, _, r in free_holes[1:]:
            self.assertEqual(r, 5.0)
        # In the pattern all six grow alike (measured 6.49925, 6e-15 apart) ...
        radii = [r for _, _, r in held_holes]
        self.assertGreater(min(radii), 6.4)
        self.assertLess(max(radii) - min(radii), 1e-10)
        # ... and stay copies turned by 60° about z (the pattern may turn as a whole; measured 3e-11 mm).
        # The designed hole's axis point has a zero mass gradient, up to quadrature round-off that
        # moved it by 2.5e-4 mm.
        for k in range(6):
            (x, y), (xn, yn) = held_holes[k][1], held_holes[(k + 1) % 6][1]
            c, s = math.cos(math.pi / 3), math.sin(math.pi / 3)
            self.assertLess(math.hypot(c * x - s * y - xn, s * x + c * y - yn), 1e-8)
            self.assertAlmostEqual(math.hypot(x, y), 32.0, delta=5e-4)
        # The objective is the written part's mass (closed form of the inspected radii).
        for h, holes in ((free, free_holes), (held, held_holes)):
            self.assertAlmostEqual(h["final_objective"] / closed_form_mass(holes), 1.0, delta=1e-9)
        self.assertAlmostEqual(held["initial_objective"] / closed_form_mass(holes_of(FLANGE)), 1.0, delta=1e-9)
        # Six holes remove six times the material of one.
        self.assertGreater(held["initial_objective"] - held["final_objective"],
                           5.9 * (free["initial_objective"] - free["final_objective"]))

    def test_bad_entries_are_named(self):
        cases = [(dict(PATTERN, degrees=50), "does not hold for the part as read"),
                 (dict(PATTERN, faces=[on_hole(0), [0, 40, 8]]), "cannot be a turned copy of face"),
                 (dict(PATTERN, faces=[on_hole(0), [0, 0, 8]]), "rotations[0].faces[1]: no face of"),
                 (dict(PATTERN, faces=[on_hole(0)]), "at least two faces"),
                 (dict(PATTERN, degrees=0), "degrees must be in (-360, 360) and not 0"),
                 (dict(PATTERN, axis={"point": [0, 0, 0], "direction": [0, 0, 0]}), "the axis is zero"),
                 (dict(PATTERN, angle=60), "rotations[0].angle: unknown key"),
                 (dict(PATTERN, faces=[on_hole(0), "hole"]), "rotations[0].faces[1] must be a face index or a point")]
        for entry, text in cases:
            with self.assertRaises(parafab.Error, msg=text) as e:
                parafab.optimize(FLANGE, dict(JOB, rotations=[entry]))
            self.assertIn(text, str(e.exception))
            self.assertIn("rotations[0]", str(e.exception))
        code, message = optimize_cli_error(FLANGE, dict(JOB, rotations=[cases[0][0]]))
        self.assertEqual(code, 2)
        self.assertIn("rotations[0]", message)


if __name__ == "__main__":
    unittest.main()
