"""The Python module converts dicts to and from the C++ JSON directly (no text round trip).
Reference: the text route json.loads(parafab.design_strip_json(json.dumps(request))), which
is what the module did before. Results must be equal value for value and type for type
(compared as JSON text, which tells 1 from 1.0), timings aside, and errors must be the same.

Run with Debian's /usr/bin/python3; PARAFAB_MODULE_DIR points at the build.
"""
import glob
import json
import math
import os
import sys
import unittest

sys.path.insert(0, os.environ.get("PARAFAB_MODULE_DIR", "build/workbench/entry"))
import parafab  # noqa: E402

HERE = os.path.dirname(os.path.abspath(__file__))
SAMPLES = os.path.join(HERE, os.pardir, os.pardir, "samples", "strips")


def untimed(x):
    if isinstance(x, dict):
        return {k: untimed(v) for k, v in x.items() if "seconds" not in k and k != "phases"}
    if isinstance(x, list):
        return [untimed(v) for v in x]
    return x


def outcome(call):
    try:
        return "ok", json.dumps(untimed(call()))
    except Exception as e:  # the error's type and message must agree too
        return type(e).__name__, str(e)


def both(request):
    direct = outcome(lambda: parafab.design_strip(request))
    text = outcome(lambda: json.loads(parafab.design_strip_json(json.dumps(request, allow_nan=True))))
    return direct, text


def ellipse(n=120):
    return [[0.2 * math.cos(t), 0.12 * math.sin(t)] for t in (0.2 + 2.7 * i / (n - 1) for i in range(n))]


BASE = {"material": {"E": 3e9, "thickness": 5e-4}, "min_width": 0.01}


class DirectConversion(unittest.TestCase):
    def test_samples_equal_the_text_route(self):
        files = sorted(glob.glob(os.path.join(SAMPLES, "*.json")))
        self.assertGreaterEqual(len(files), 5)
        for f in files:
            with open(f) as fh:
                request = json.load(fh)
            direct, text = both(request)
            self.assertEqual(direct, text, f)
            self.assertEqual(direct[0], "ok", f)

    def test_value_types_and_unicode(self):
        # Tuples as arrays, ints for a count, a non-ASCII name echoed back, gravity, validation.
        request = dict(BASE, curve={"points": tuple(tuple(p) for p in ellipse())}, samples=200,
                       name="Bogen \u00e4 \u20ac", validate={"edges": 50},
                       gravity={"direction": [0, -1], "beta_l3": 8.86e-4})
        direct, text = both(request)
        self.assertEqual(direct, text)
        result = parafab.design_strip(request)
        self.assertEqual(result["name"], "Bogen \u00e4 \u20ac")
        self.assertIs(type(result["diagnostics"]["samples"]), int)
        self.assertIs(type(result["R"]), float)
        self.assertIsNone(result["where"])

    def test_errors_are_the_same(self):
        # NaN: the message the module has always given (the text entry reports a JSON syntax
        # error instead, NaN not being JSON).
        nan = dict(BASE, curve={"points": [[0, 0], [0.1, float("nan")], [0.2, 0.0]]})
        self.assertEqual(both(nan)[0], ("Error", "the request contains NaN or infinite numbers"))
        cases = [
            dict(BASE, curve={"points": ellipse()}, samples=2 ** 70),  # beyond 64 bits
            dict(BASE, curve={"points": ellipse()}, samples=-3),
            dict(BASE, curve={"points": ellipse()}, samples=True),
            dict(BASE, curve={"points": ellipse()}, samples=12.0),
            dict(BASE, curve={"points": ellipse()}, name=7),
            {1: 2, "material": BASE["material"]},  # a non-string key: the text route decides
            dict(BASE, curve={"points": ellipse()}, tolerance=object()),  # not JSON at all
        ]
        for request in cases:
            direct, text = both(request)
            self.assertEqual(direct, text, repr(request)[:80])
            self.assertNotEqual(direct[0], "ok", repr(request)[:80])
        self.assertEqual(both(cases[-1])[0][0], "TypeError")

    def test_text_entry_rejects_bad_json(self):
        with self.assertRaises(parafab.Error) as ctx:
            parafab.design_strip_json("{not json")
        self.assertIn("not valid JSON", str(ctx.exception))


if __name__ == "__main__":
    unittest.main()
