"""End-to-end strip design through Python (issue 13, "Speed"): a curve given as 400 points
to a designed strip (interpolation, zeros, sampling, LP, outline, JSON), median wall time of
``parafab.design_strip`` over repeats, beside the solver's own total and LP times.

    /usr/bin/python3 tests/bench/bench_strip_python.py [--quick] [--repeats N] [--out DIR]
        [--baseline OLD.json]      -> DIR/strip_python.json, DIR/strip_python.png
    valgrind --tool=callgrind /usr/bin/python3 tests/bench/bench_strip_python.py --calls-only CASE N

Curves (400 points each, metres): an ellipse arc (no inflection), a cubic with one
inflection, and the same ellipse arc under cardboard gravity (the general LP).

Per case: the median of every phase the call reports (``diagnostics.phases``: interpolation
of the points, arc-length table, zeros, equilibrium check, sampling, LPs, continuous-ratio
estimate, widths/outline, stability verdict, and ``entry`` = the whole C++ call), the
Python<->C++ conversion (call minus entry; the previous result is freed before each timed
call, and that release is reported on its own), and, as baselines in the same run, the text
route ``json.loads(parafab.design_strip_json(json.dumps(request)))`` (what design_strip did
before the direct dict conversion; its result is checked equal) and the call with the LPs
solved by Clp's dual form (``"lp_form": "dual"``, the solver before the dense one; R checked
equal to 1e-10, Clp's own primal and dual forms differing by up to 2.8e-11). With ``--baseline`` (a JSON
written by an earlier build), the ratios old / new are reported too.
"""

import argparse
import json
import math
import os
import statistics
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.normpath(os.path.join(HERE, os.pardir, os.pardir))
sys.path.insert(0, os.environ.get("PARAFAB_MODULE_DIR") or os.path.join(REPO, "build", "workbench", "entry"))
import parafab  # noqa: E402


def ellipse_points(n=400):
    return [[0.2 * math.cos(t), 0.12 * math.sin(t)]
            for t in (0.2 + 2.7 * i / (n - 1) for i in range(n))]


def cubic_points(n=400):
    pts = []
    for i in range(n):
        x = -0.135 + 0.27 * i / (n - 1)
        u = x / 0.15
        pts.append([x, 0.06 * (u ** 3 - u)])
    return pts


def cases():
    base = {"material": {"E": 3e9, "thickness": 0.5e-3}, "min_width": 0.01}
    out = []
    out.append(("ellipse_400", dict(base, curve={"points": ellipse_points()})))
    out.append(("one_inflection_400", dict(base, curve={"points": cubic_points()})))
    out.append(("ellipse_400_gravity", dict(
        base, curve={"points": ellipse_points()},
        material={"E": 0.773e9, "thickness": 0.3e-3, "density": 667},
        gravity={"direction": [0, -1]})))
    return out


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--repeats", type=int, default=51)
    ap.add_argument("--out", default=".")
    ap.add_argument("--baseline")
    ap.add_argument("--calls-only", nargs=2, metavar=("CASE", "N"),
                    help="only call design_strip N times on CASE, untimed (for callgrind: the "
                         "instructions per call are the difference between two N)")
    args = ap.parse_args()
    if args.calls_only:
        known = dict(cases())
        if args.calls_only[0] not in known:
            ap.error("--calls-only: unknown case %r (known: %s)" % (args.calls_only[0], ", ".join(known)))
        spec = known[args.calls_only[0]]
        for _ in range(int(args.calls_only[1])):
            parafab.design_strip(spec)
        return
    repeats = 5 if args.quick else args.repeats
    baseline = {}
    if args.baseline:
        with open(args.baseline) as f:
            baseline = {c["name"]: c for c in json.load(f)["cases"]}
    rows = []
    for name, spec in cases():
        parafab.design_strip(spec)  # warm-up
        wall, cpu, total, lp, text, clp, clp_lp = [], [], [], [], [], [], []
        phases = {}
        clp_spec = dict(spec, lp_form="dual")  # Clp's dual form: the LP solver before the dense one
        release = []
        r = rt = rc = None
        for _ in range(repeats):
            # The previous iteration's results are freed before the timed call, not inside it
            # (rebinding r would free ~15,000 Python objects within the timing); that release
            # is timed on its own.
            t0 = time.perf_counter()
            had = r is not None
            r = None
            if had:
                release.append(time.perf_counter() - t0)
            rt = rc = None
            t0, c0 = time.perf_counter(), time.process_time()
            r = parafab.design_strip(spec)
            wall.append(time.perf_counter() - t0)
            cpu.append(time.process_time() - c0)
            total.append(r["diagnostics"]["total_seconds"])
            lp.append(r["diagnostics"]["lp_seconds"])
            for k, v in r["diagnostics"]["phases"].items():
                phases.setdefault(k, []).append(v)
            phases.setdefault("conversion", []).append(wall[-1] - r["diagnostics"]["phases"]["entry"])
            t0 = time.perf_counter()
            rt = json.loads(parafab.design_strip_json(json.dumps(spec)))
            text.append(time.perf_counter() - t0)
            t0 = time.perf_counter()
            rc = parafab.design_strip(clp_spec)
            clp.append(time.perf_counter() - t0)
            clp_lp.append(rc["diagnostics"]["phases"]["lp"])
        # Clp ends within its feasibility tolerances: its primal and dual forms differ by up to
        # 2.8e-11 in R on the one-inflection curve, so compare to 1e-10.
        if abs(rc["R"] / r["R"] - 1) > 1e-10:
            raise SystemExit("%s: R with Clp %.17g differs from the dense LP's %.17g" % (name, rc["R"], r["R"]))
        if untimed(rt) != untimed(r):
            raise SystemExit("%s: the text route's result differs from design_strip's" % name)
        row = {"name": name, "repeats": repeats, "feasible": r["feasible"], "R": r["R"],
               "samples": r["diagnostics"]["samples"],
               "python_ms_median": 1e3 * statistics.median(wall),
               "python_ms_min": 1e3 * min(wall),
               "python_cpu_ms_median": 1e3 * statistics.median(cpu),
               "design_ms_median": 1e3 * statistics.median(total),
               "lp_ms_median": 1e3 * statistics.median(lp),
               "text_route_ms_median": 1e3 * statistics.median(text),
               "clp_python_ms_median": 1e3 * statistics.median(clp),
               "clp_lp_phase_ms_median": 1e3 * statistics.median(clp_lp), "clp_R": rc["R"],
               "phases_ms_median": {k: 1e3 * statistics.median(v) for k, v in phases.items()},
               "release_ms_median": 1e3 * statistics.median(release) if release else None}
        row["text_route_ratio"] = row["text_route_ms_median"] / row["python_ms_median"]
        row["clp_ratio"] = row["clp_python_ms_median"] / row["python_ms_median"]
        old = baseline.get(name)
        if old:
            row["baseline_python_ms_median"] = old["python_ms_median"]
            row["speedup"] = old["python_ms_median"] / row["python_ms_median"]
            row["baseline_R"] = old["R"]
        rows.append(row)
        print("%-22s R = %.6f, %4d samples: python %.2f ms (min %.2f, CPU %.2f), design %.2f ms, LP %.2f ms;"
              " text route %.2f ms (%.2fx)%s"
              % (name, r["R"], row["samples"], row["python_ms_median"], row["python_ms_min"],
                 row["python_cpu_ms_median"],
                 row["design_ms_median"], row["lp_ms_median"], row["text_route_ms_median"],
                 row["text_route_ratio"],
                 "  (baseline %.2f ms: %.1fx)" % (old["python_ms_median"], row["speedup"]) if old else ""))
        print("    phases [ms]: " + ", ".join("%s %.3f" % (k, v) for k, v in row["phases_ms_median"].items())
              + ("; freeing the previous result (untimed above) %.3f" % row["release_ms_median"]
                 if row["release_ms_median"] is not None else ""))
        print("    with Clp's dual form (same run): python %.2f ms (%.2fx the dense LP's), LP phase %.3f ms (%.1fx)"
              % (row["clp_python_ms_median"], row["clp_ratio"], row["clp_lp_phase_ms_median"],
                 row["clp_lp_phase_ms_median"] / row["phases_ms_median"]["lp"]))
    os.makedirs(args.out, exist_ok=True)
    path = os.path.join(args.out, "strip_python.json")
    with open(path, "w") as f:
        json.dump({"benchmark": "strip_python", "cases": rows}, f, indent=2)
    png = os.path.join(args.out, "strip_python.png")
    plot(rows, png)
    print("->", path, png)


def untimed(x):
    """The result without its timings (they differ between any two calls)."""
    if isinstance(x, dict):
        return {k: untimed(v) for k, v in x.items() if "seconds" not in k and k != "phases"}
    if isinstance(x, list):
        return [untimed(v) for v in x]
    return x


PHASES = ["interpolation", "curve", "zeros", "check", "sampling", "lp", "ratio", "outputs",
          "stability", "json", "conversion"]


def plot(rows, png):
    """Bars per case: Python call, design (C++), LP; the baseline's Python call if given."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, (ax, ax2) = plt.subplots(1, 2, figsize=(12, 4.5))
    x = range(len(rows))
    keys = [("text_route_ms_median", "text route (same run)"), ("clp_python_ms_median", "LP by Clp (same run)"),
            ("python_ms_median", "parafab.design_strip (Python)"), ("design_ms_median", "design (C++)"),
            ("lp_ms_median", "final LP")]
    if all("baseline_python_ms_median" in r for r in rows):
        keys.insert(0, ("baseline_python_ms_median", "baseline Python call"))
    width = 0.8 / len(keys)
    for k, (key, label) in enumerate(keys):
        ax.bar([i + k * width for i in x], [r[key] for r in rows], width, label=label)
    ax.axhline(2.0, color="gray", ls="--", label="goal 2 ms")
    ax.set_xticks([i + 0.4 - width / 2 for i in x])
    ax.set_xticklabels([r["name"] for r in rows], fontsize=8)
    ax.set_ylabel("median time [ms]")
    ax.set_yscale("log")
    ax.legend(fontsize=8)
    # Stacked phases of the Python call ("json": the rest of the C++ entry, mostly building
    # the result; "conversion": dict <-> C++).
    bottom = [0.0] * len(rows)
    for k in PHASES:
        vals = []
        for r in rows:
            ph = r["phases_ms_median"]
            if k == "json":
                named = sum(ph.get(q, 0) for q in PHASES if q not in ("json", "conversion"))
                vals.append(max(ph["entry"] - named, 0))
            else:
                vals.append(ph.get(k, 0))
        ax2.bar(list(x), vals, 0.6, bottom=bottom, label=k, color=plt.cm.tab20(PHASES.index(k)))
        bottom = [b + v for b, v in zip(bottom, vals)]
    ax2.axhline(2.0, color="gray", ls="--")
    ax2.set_xticks(list(x))
    ax2.set_xticklabels([r["name"] for r in rows], fontsize=8)
    ax2.set_ylabel("median per phase [ms], stacked")
    ax2.legend(fontsize=7, ncol=2)
    fig.tight_layout()
    fig.savefig(png, dpi=100)


if __name__ == "__main__":
    main()
