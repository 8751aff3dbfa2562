"""`parafab integrate` (CLI) and parafab.integrate_part (Python) on the sample parts:
mass properties by cut-cell quadrature against OpenCASCADE's BRepGProp, same JSON on both
entry points, and clear errors for bad input (CLI: exit 2 and a JSON error)."""
import json
import os
import subprocess
import sys
import tempfile
import unittest

sys.path.insert(0, os.environ.get("PARAFAB_MODULE_DIR", "build/workbench/entry"))
import parafab  # noqa: E402

CLI = os.environ.get("PARAFAB_CLI", "build/workbench/entry/parafab")
PARTS = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "samples", "parts")


def cli(*args):
    p = subprocess.run([CLI, "integrate", *args], capture_output=True, text=True, timeout=300)
    return p.returncode, json.loads(p.stdout)


class Integrate(unittest.TestCase):
    def test_parts_match_occt(self):
        for name in ["wrench", "wheel", "housing"]:
            with self.subTest(name):
                r = parafab.integrate_part(os.path.join(PARTS, name + ".step"), cells=6)
                e = r["relative_errors"]
                self.assertLess(e["volume"], 1e-8)
                self.assertLess(e["center"], 1e-8)
                self.assertLess(e["inertia"], 1e-8)
                self.assertEqual(r["diagnostics"]["rules_not_ok"], 0)
                self.assertGreater(r["grid"]["cut_cells"], 0)

    def test_cli_equals_module_and_linear_segments_are_coarser(self):
        path = os.path.join(PARTS, "ring.step")
        code, out = cli(path, "--cells", "5")
        self.assertEqual(code, 0)
        mod = parafab.integrate_part(path, cells=5)
        self.assertEqual(out["rules"]["volume"], mod["rules"]["volume"])
        _, lin = cli(path, "--cells", "5", "--segments", "linear")
        self.assertEqual(lin["grid"]["segment_order"], 1)
        self.assertGreater(lin["grid"]["curve_segments"], out["grid"]["curve_segments"])

    def test_cut_by_face_on_both_entry_points(self):
        # Planes and cylinders (closed forms) and tori (traced): the face route.
        path = os.path.join(PARTS, "wrench.step")
        code, out = cli(path, "--cells", "6")
        self.assertEqual(code, 0)
        self.assertEqual(out["grid"]["method"], "face")
        self.assertEqual(out["grid"]["retry_reason"], "")
        self.assertLess(out["relative_errors"]["volume"], 1e-11)
        mod = parafab.integrate_part(path, cells=6)
        self.assertEqual(out["rules"]["volume"], mod["rules"]["volume"])
        # A torus (the housing's boss fillet): the face route's traced level curves.
        torus = parafab.integrate_part(os.path.join(PARTS, "housing.step"), cells=6)
        self.assertEqual(torus["grid"]["method"], "face")
        self.assertEqual(torus["grid"]["retry_reason"], "")
        self.assertLess(torus["relative_errors"]["volume"], 1e-11)
        with self.assertRaises(TypeError):  # the splitter is no longer a user route
            parafab.integrate_part(path, cut="splitter")
        p = subprocess.run([CLI, "integrate", path, "--cut", "splitter"], capture_output=True, text=True, timeout=60)
        self.assertNotEqual(p.returncode, 0)
        self.assertIn("--cut", p.stdout + p.stderr)

    def test_bad_input(self):
        with tempfile.TemporaryDirectory() as d:
            text = os.path.join(d, "notes.step")
            with open(text, "w") as f:
                f.write("this is not a STEP file\n")
            empty = os.path.join(d, "empty.step")
            open(empty, "w").close()
            for path, expected in [(os.path.join(d, "missing.step"), "not found"), (text, text), (empty, "empty")]:
                with self.subTest(path):
                    code, out = cli(path)
                    self.assertEqual(code, 2)
                    self.assertIn(expected, out["error"]["message"])
                    with self.assertRaises(parafab.Error):
                        parafab.integrate_part(path)
        code, out = cli(os.path.join(PARTS, "box.step"), "--cells", "0")
        self.assertEqual(code, 2)
        self.assertEqual(out["error"]["kind"], "usage")

    def test_too_large_grid_is_refused_with_its_estimate(self):
        # 100000 cells along the bracket: ~1e14 cells; refused before cutting, as simulate does,
        # with the estimate in the message and how to override it (--force).
        path = os.path.join(PARTS, "l_bracket.step")
        code, out = cli(path, "--cells", "100000")
        self.assertEqual(code, 2, out)
        msg = out["error"]["message"]
        for expected in ("cells", "MB", "memory", "--force", "--cells"):
            self.assertIn(expected, msg)
        with self.assertRaisesRegex(parafab.Error, "force=True"):
            parafab.integrate_part(path, cells=100000)
        # the estimate alone: cells per axis from the bounding box (60 x 40 x 40 mm part on
        # 100000 / 60 mm cells: 66667 x 66667 x 100000 would be the bracket's; check the product)
        code, est = cli(path, "--cells", "100000", "--estimate")
        self.assertEqual(code, 0, est)
        e = est["estimate"]
        self.assertFalse(e["fits"])
        self.assertAlmostEqual(e["cells_total"], e["cells"][0] * e["cells"][1] * e["cells"][2], delta=1e-6 * e["cells_total"])
        self.assertEqual(max(e["cells"]), 100000)
        self.assertGreater(e["memory_mb"], e["physical_mb"])
        # a small grid fits, and its estimate is near the cut it then makes
        code, small = cli(path, "--cells", "12")
        self.assertEqual(code, 0, small)
        self.assertTrue(small["estimate"]["fits"])
        self.assertEqual(small["estimate"]["cells"], small["grid"]["cells"])
        ratio = small["estimate"]["cut_cells"] / small["grid"]["cut_cells"]
        print("cut cells estimated / made at 12 cells: %.2f" % ratio)
        self.assertTrue(0.5 < ratio < 2, ratio)


if __name__ == "__main__":
    unittest.main()
