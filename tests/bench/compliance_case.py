"""What the compliance-optimization benchmarks of thesis Table 6.1 share (bench_optimize_plate.py,
bench_optimize_housing.py): run `parafab.optimize`, check the written part afresh by
`parafab.simulate` on a finer grid and by Gmsh + CalculiX tet10 (before and after), and time one
CalculiX run as the unit of the route without ParaFab's gradient (a forward-difference gradient
over n parameters costs n + 1 runs: an estimate from one measured run, labelled as such)."""
import argparse
import json
import os
import subprocess
import sys
import tempfile
import time

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.normpath(os.path.join(HERE, "..", ".."))
sys.path.insert(0, os.environ.get("PARAFAB_MODULE_DIR", os.path.join(REPO, "build", "workbench", "entry")))
import parafab  # noqa: E402

REF = os.path.join(REPO, "tests", "reference", "calculix_reference.py")


def arguments(default_iterations, positions=False, extra=None):
    """--quick (1 iteration, no CalculiX), --iterations, --gradient, --out (created); with
    positions=True also --positions (the case's extra design variables); extra(parser) adds a
    case's own options."""
    ap = argparse.ArgumentParser()
    if positions:
        ap.add_argument("--positions", action="store_true", help="also the holes' centres as design variables")
    if extra:
        extra(ap)
    ap.add_argument("--quick", action="store_true", help="1 iteration, no CalculiX run")
    ap.add_argument("--iterations", type=int, default=default_iterations)
    ap.add_argument("--gradient", choices=("exact", "semi-analytic"), default="exact",
                    help="route of the compliance gradient (objective.gradient)")
    ap.add_argument("--out", default=".")
    a = ap.parse_args()
    os.makedirs(a.out, exist_ok=True)
    return a


def report(out_dir, name, history, summary):
    """Writes out_dir/name.json ({summary, history}) and prints the summary."""
    with open(os.path.join(out_dir, name + ".json"), "w") as f:
        json.dump({"summary": summary, "history": history}, f, indent=2)
    print(json.dumps(summary, indent=2))


def run(part, sim, job, out_dir, fresh_cells, calculix_size=None):
    """Optimizes `part` with `job` (which holds `sim`'s fields), writes into out_dir; returns
    (history, summary) with timings, the objective change, the fresh simulation on fresh_cells
    and, when calculix_size is given, CalculiX before and after at that mesh size."""
    t0 = time.perf_counter()
    h = parafab.optimize(part, job, out_dir=out_dir)
    wall = time.perf_counter() - t0
    n = max(len(h["iterations"]) - 1, 1)

    def fresh(path):
        return -2 * parafab.simulate(path, dict(sim, grid={"cells": fresh_cells}))["potential"]

    c0, c1 = fresh(part), fresh(h["optimized_step"])
    summary = {
        "parameters": len(h["parameters"]), "iterations": n, "evaluations": h["evaluations"],
        "status": h["status"], "message": h["message"], "seconds": wall,
        "seconds_per_iteration": h["seconds"] / n,
        "seconds_per_evaluation": h["seconds"] / max(h["evaluations"], 1),
        "objective": {"initial": h["initial_objective"], "final": h["final_objective"],
                      "change": h["final_objective"] / h["initial_objective"] - 1},
        "fresh_%d_cells" % fresh_cells: {"initial": c0, "final": c1, "change": c1 / c0 - 1},
        "volume_ratio": h["final_volume"] / h["initial_volume"],
        "gradient_initial": [p["gradient_initial"] for p in h["parameters"]],
        "gradient": h["gradient"], "exact_derivatives": h.get("exact_derivatives", 0),
        "semi_analytic_derivatives": h.get("semi_analytic_derivatives", 0),
        "invalid_models": h["invalid_models"],
    }
    if calculix_size:
        with tempfile.NamedTemporaryFile("w", suffix=".json", delete=False) as f:
            json.dump(sim, f)
        try:
            def calculix(path):
                out = subprocess.run(["/usr/bin/python3", REF, f.name, "--parafab", path, "--size",
                                      str(calculix_size), "--quiet"], capture_output=True, text=True, check=True).stdout
                return json.loads(out)["compliance"]

            t0 = time.perf_counter()
            before = calculix(part)
            one = time.perf_counter() - t0
            after = calculix(h["optimized_step"])  # the written part, checked by an independent solver
        finally:
            os.unlink(f.name)
        summary["calculix"] = {"size": calculix_size, "seconds_one_run": one, "compliance": before,
                               "compliance_optimized": after, "change": after / before - 1,
                               "forward_difference_gradient_seconds_estimate": (len(h["parameters"]) + 1) * one}
    return h, summary
