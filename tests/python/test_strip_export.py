"""Cut sheets of strips (parafab strip --dxf/--svg, parafab.export_strip_outline) read back
with plain Python: the outline polygon's length and its width at several s must match the
JSON result to 1e-6 m (compared in mm), composite strips carry both layers, perforated strips
their holes, and the name, clamp positions and end angles are annotated.

Run with Debian's /usr/bin/python3; PARAFAB_MODULE_DIR and PARAFAB_CLI point at the build.
"""
import json
import math
import os
import subprocess
import sys
import tempfile
import unittest
import xml.etree.ElementTree as ET

import numpy as np

sys.path.insert(0, os.environ.get("PARAFAB_MODULE_DIR", "build/workbench/entry"))
import parafab  # noqa: E402

CLI = os.environ.get("PARAFAB_CLI", "build/workbench/entry/parafab")
TOL_MM = 1e-3  # 1e-6 m


def ellipse_arc(n=301):
    t = np.linspace(0.2, 2.9, n)
    return np.c_[0.2 * np.cos(t), 0.12 * np.sin(t)].tolist()


def request(**extra):
    r = {"name": "ellipse arch", "curve": {"points": ellipse_arc(), "degree": 5},
         "material": {"E": 3e9, "thickness": 3e-4}, "min_width": 0.02,
         "gravity": {"direction": [0, -1], "beta_l3": 8.86e-4}}
    r.update(extra)
    return r


def read_dxf(path):
    """(polygons {layer: [[(x, y), ...], ...]}, lines [(layer, x1, y1, x2, y2)], texts [(layer, text)])."""
    with open(path) as f:
        raw = f.read().splitlines()
    assert len(raw) % 2 == 0, "DXF must be (code, value) line pairs"
    pairs = [(int(raw[i].strip()), raw[i + 1]) for i in range(0, len(raw), 2)]
    assert pairs[-1] == (0, "EOF")
    header = dict()
    for i, (c, v) in enumerate(pairs):
        if c == 9:
            header[v] = pairs[i + 1][1]
    assert header["$ACADVER"] == "AC1009"
    # split into entities at group code 0
    ents, cur = [], None
    for c, v in pairs:
        if c == 0:
            cur = [v, {}]
            ents.append(cur)
        elif cur is not None:
            cur[1].setdefault(c, []).append(v)
    polys, lines, texts = {}, [], []
    poly = None
    for kind, g in ents:
        if kind == "POLYLINE":
            assert int(g[70][0]) & 1, "outline polylines must be closed"
            poly = (g[8][0], [])
        elif kind == "VERTEX":
            poly[1].append((float(g[10][0]), float(g[20][0])))
        elif kind == "SEQEND":
            polys.setdefault(poly[0], []).append(poly[1])
            poly = None
        elif kind == "LINE":
            lines.append((g[8][0], float(g[10][0]), float(g[20][0]), float(g[11][0]), float(g[21][0])))
        elif kind == "TEXT":
            texts.append((g[8][0], g[1][0]))
    return polys, lines, texts


def read_svg(path):
    ns = {"s": "http://www.w3.org/2000/svg"}
    root = ET.parse(path).getroot()
    assert root.get("width").endswith("mm") and root.get("height").endswith("mm")
    vb = [float(v) for v in root.get("viewBox").split()]
    assert abs(vb[2] - float(root.get("width")[:-2])) < 1e-3  # 1 user unit = 1 mm
    polys = {}
    for g in root.findall("s:g", ns):
        for p in g.findall("s:polygon", ns):
            pts = [tuple(float(c) for c in xy.split(",")) for xy in p.get("points").split()]
            polys.setdefault(g.get("id"), []).append([(x, -y) for x, y in pts])  # y mirrored
    texts = [t.text for t in root.iter("{http://www.w3.org/2000/svg}text")]
    lines = root.findall("s:g[@id='CLAMPS']/s:line", ns)
    return polys, lines, texts, vb


def width_at(poly, x):
    ys = [y for px, y in poly if abs(px - x) <= 1e-6]
    assert len(ys) >= 2, f"no outline vertices at x = {x} mm"
    return max(ys) - min(ys)


class Export(unittest.TestCase):
    def check_band(self, poly, s, w, length):
        xs = [p[0] for p in poly]
        self.assertAlmostEqual(min(xs), 0.0, delta=TOL_MM)
        self.assertAlmostEqual(max(xs), 1000 * length, delta=TOL_MM)
        for i in np.linspace(0, len(s) - 1, 7).astype(int):
            self.assertAlmostEqual(width_at(poly, 1000 * s[i]), 1000 * w[i], delta=TOL_MM)
            ys = [y for px, y in poly if abs(px - 1000 * s[i]) <= 1e-6]
            self.assertAlmostEqual(max(ys) + min(ys), 0.0, delta=TOL_MM)  # symmetric

    def check_annotations(self, texts, result):
        joined = "\n".join(texts)
        self.assertIn("ellipse arch", joined)
        for end in result["ends"]:
            word = "START" if end["which"] == "start" else "END"
            line = [t for t in texts if t.startswith(word + " clamp")]
            self.assertEqual(len(line), 1, joined)
            self.assertIn(f"s={1000 * end['s']:.2f} mm", line[0])
            self.assertIn(f"angle={end['angle_deg']:.2f} deg", line[0])

    def test_cli_dxf_and_svg(self):
        with tempfile.TemporaryDirectory() as d:
            inp, out = os.path.join(d, "in.json"), os.path.join(d, "out.json")
            dxf, svg = os.path.join(d, "strip.dxf"), os.path.join(d, "strip.svg")
            with open(inp, "w") as f:
                json.dump(request(), f)
            p = subprocess.run([CLI, "strip", inp, "-o", out, "--dxf", dxf, "--svg", svg],
                               capture_output=True, text=True, timeout=120)
            self.assertEqual(p.returncode, 0, p.stdout + p.stderr)
            with open(out) as f:
                r = json.load(f)
            self.assertTrue(r["feasible"])
            polys, lines, texts = read_dxf(dxf)
            self.assertEqual(list(polys), ["OUTLINE"])
            self.check_band(polys["OUTLINE"][0], r["s"], r["width"], r["length"])
            self.assertEqual(len([l for l in lines if l[0] == "CLAMPS"]), 2)
            self.assertEqual({l[1] for l in lines}, {0.0, round(1000 * r["length"], 6)})
            self.check_annotations([t for _, t in texts], r)
            spolys, slines, stexts, vb = read_svg(svg)
            self.check_band(spolys["OUTLINE"][0], r["s"], r["width"], r["length"])
            self.assertEqual(len(slines), 2)
            self.check_annotations(stexts, r)
            self.assertLessEqual(vb[0], 0.0)
            self.assertGreaterEqual(vb[0] + vb[2], 1000 * r["length"])
            print(f"\n  outline {1000 * r['length']:.3f} mm long, width {1000 * min(r['width']):.3f}"
                  f"..{1000 * max(r['width']):.3f} mm, {len(polys['OUTLINE'][0])} vertices")

    def test_composite_has_both_layers(self):
        r = parafab.design_strip(request(composite={"h1": 3e-4, "h2": 3e-4, "outer_width": 0.05}))
        c = r["composite"]
        self.assertTrue(c["feasible"], c["message"])
        with tempfile.TemporaryDirectory() as d:
            for ext in ("dxf", "svg"):
                path = os.path.join(d, "c." + ext)
                parafab.export_strip_outline(r, path)
                polys = read_dxf(path)[0] if ext == "dxf" else read_svg(path)[0]
                self.assertEqual(sorted(polys), ["INNER", "OUTER"])
                self.check_band(polys["OUTER"][0], r["s"], [0.05] * len(r["s"]), r["length"])
                self.check_band(polys["INNER"][0], r["s"], c["w2"], r["length"])

    def test_perforated_has_holes(self):
        r = parafab.design_strip(request(perforated={"outer_width": 0.04, "min_ligament": 1e-3}))
        p = r["perforations"]
        self.assertTrue(p["feasible"], p["message"])
        with tempfile.TemporaryDirectory() as d:
            path = os.path.join(d, "p.dxf")
            parafab.export_strip_outline(r, path)
            polys, _, texts = read_dxf(path)
            self.assertEqual(len(polys["HOLES"]), len(p["diamonds"]))
            self.check_band(polys["OUTLINE"][0], r["s"], [0.04] * len(r["s"]), r["length"])
            d0 = p["diamonds"][0]
            hole = np.array(polys["HOLES"][0])
            self.assertAlmostEqual(hole[:, 0].max() - hole[:, 0].min(), 1000 * d0["length"], delta=TOL_MM)
            self.assertAlmostEqual(hole[:, 1].max() - hole[:, 1].min(), 1000 * d0["width"], delta=TOL_MM)

    def test_errors(self):
        here = os.path.dirname(os.path.abspath(__file__))
        with open(os.path.join(here, "..", "..", "samples", "strips", "infeasible_crossing.json")) as f:
            infeasible = parafab.design_strip(json.load(f))
        self.assertFalse(infeasible["feasible"])
        with tempfile.TemporaryDirectory() as d:
            with self.assertRaises(parafab.Error) as cm:
                parafab.export_strip_outline(infeasible, os.path.join(d, "x.dxf"))
            self.assertIn("infeasible", str(cm.exception))
            r = parafab.design_strip(request())
            with self.assertRaises(parafab.Error) as cm:
                parafab.export_strip_outline(r, os.path.join(d, "x.pdf"))
            self.assertIn("must end in .dxf or .svg", str(cm.exception))
            inp = os.path.join(d, "in.json")
            with open(inp, "w") as f:
                json.dump(request(), f)
            p = subprocess.run([CLI, "strip", inp, "--dxf", os.path.join(d, "no", "such", "dir.dxf")],
                               capture_output=True, text=True, timeout=120)
            self.assertEqual(p.returncode, 2)
            self.assertIn("cannot write outline file", json.loads(p.stdout)["error"]["message"])


if __name__ == "__main__":
    unittest.main()
