"""The XFEM solve at scale: unknowns against time (each phase) and peak memory for CHOLMOD and
PETSc (CG + GAMG) on the sample L-bracket, hex8, turned 17 degrees off the grid (the sample job
of tests/python/test_simulate_threads.py), one rank with 2 threads; PETSc also on 2 ranks x 1
thread against 1 rank x 1 thread. Accuracy: PETSc's potential, largest displacement and von Mises
stress against CHOLMOD's on the same grid where both run (the solver's own error, rtol 1e-9).
Each case runs `repeats` times; the medians are reported.

Usage: /usr/bin/python3 tests/bench/bench_xfem_scale.py [--cells 16,24,...] [--cholmod-max 64]
       [--repeats 3] [--ranks-cells 64] [--out DIR]
Writes DIR/xfem_scale.json and DIR/xfem_scale.png."""
import argparse
import json
import os
import re
import shutil
import statistics
import subprocess
import sys
import tempfile

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.normpath(os.path.join(HERE, "..", ".."))
sys.path.insert(0, os.path.join(REPO, "tests", "python"))
CLI = os.environ.get("PARAFAB_CLI", os.path.join(REPO, "build", "workbench", "entry", "parafab"))
os.environ.setdefault("PARAFAB_CLI", CLI)
from test_simulate_threads import BRACKET, bracket_job  # noqa: E402


def run_once(cells, solver, ranks=1, threads=2):
    job = dict(bracket_job(cells), element="hex8", threads=threads, solver=solver, memory_limit_mb=22000)
    job.pop("probes", None)
    with tempfile.NamedTemporaryFile("w", suffix=".json", delete=False) as f:
        json.dump(job, f)
    cmd = ["/usr/bin/time", "-v"]
    if ranks > 1:
        cmd += [shutil.which("mpirun"), "--allow-run-as-root", "--oversubscribe", "-np", str(ranks)]
    cmd += [CLI, "simulate", BRACKET, f.name]
    p = subprocess.run(cmd, capture_output=True, text=True)
    os.unlink(f.name)
    if p.returncode != 0:
        return {"error": (p.stdout[-400:] + p.stderr[-400:])}
    d = json.loads(p.stdout)
    rss = int(re.search(r"Maximum resident set size \(kbytes\): (\d+)", p.stderr).group(1)) / 1024.0
    s = d["seconds"]
    return {"dofs": d["dofs"], "cut_cells": d["grid"]["cut_cells"], "potential": d["potential"],
            "max_displacement": d["max_displacement"], "max_von_mises": d["max_von_mises"],
            "method": d["solver"]["method"], "iterations": d["solver"]["iterations"],
            "residual": d["solver"]["residual"], "ranks": d["solver"].get("ranks", 1),
            "cut": s["cut"], "rules": s["rules"], "assemble": s["assemble"], "solve": s["solve"],
            "results": s.get("results", 0), "petsc_setup": s.get("solve_parts", {}).get("petsc_setup", 0),
            "peak_mb": rss}


def run(cells, solver, repeats, ranks=1, threads=2):
    runs = [run_once(cells, solver, ranks, threads) for _ in range(repeats)]
    ok = [r for r in runs if "error" not in r]
    if not ok:
        return runs[0]
    out = dict(ok[0])
    for k in ("cut", "rules", "assemble", "solve", "results", "petsc_setup", "peak_mb"):
        out[k] = statistics.median(r[k] for r in ok)
    out["total"] = out["cut"] + out["rules"] + out["assemble"] + out["solve"] + out["results"]
    out["repeats"] = len(ok)
    return out


def rel(a, b):
    return abs(a - b) / max(abs(a), abs(b), 1e-300)


def chart(rows, path):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(11, 4.2))
    for name, style in (("cholmod", "o-"), ("petsc", "s-")):
        rs = [r for r in rows if r["solver"] == name and r["ranks"] == 1 and "dofs" in r]
        if not rs:
            continue
        x = [r["dofs"] for r in rs]
        a1.loglog(x, [r["total"] for r in rs], style, label=f"{name}: total")
        a1.loglog(x, [r["solve"] for r in rs], style.replace("-", "--"), alpha=0.6, label=f"{name}: solve")
        a2.loglog(x, [r["peak_mb"] for r in rs], style, label=name)
    rs = [r for r in rows if r["solver"] == "petsc" and "dofs" in r]
    if rs:
        x = [r["dofs"] for r in rs]
        a1.loglog(x, [r["rules"] for r in rs], "^:", color="gray", label="cut-cell rules")
    a1.set_xlabel("unknowns")
    a1.set_ylabel("seconds (median)")
    a1.set_title("L-bracket hex8, turned 17°: time (1 rank, 2 threads)")
    a1.legend(fontsize=8)
    a1.grid(True, which="both", alpha=0.3)
    a2.set_xlabel("unknowns")
    a2.set_ylabel("peak memory (MB)")
    a2.set_title("peak resident memory")
    a2.legend(fontsize=8)
    a2.grid(True, which="both", alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=110)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--cells", default="16,24,32,48,64,96,128")
    ap.add_argument("--cholmod-max", type=int, default=64)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--ranks-cells", type=int, default=64)
    ap.add_argument("--out", default=os.path.join(REPO, "build", "bench"))
    a = ap.parse_args()
    os.makedirs(a.out, exist_ok=True)
    rows = []
    for cells in [int(c) for c in a.cells.split(",")]:
        for name in ("cholmod", "petsc"):
            if name == "cholmod" and cells > a.cholmod_max:
                continue
            reps = a.repeats if cells <= 64 else 1
            r = run(cells, {"type": name}, reps)
            r.update(solver=name, cells=cells, ranks=r.get("ranks", 1))
            rows.append(r)
            print(json.dumps(r), flush=True)
    if a.ranks_cells:
        for ranks, threads in ((1, 1), (2, 1)):
            r = run(a.ranks_cells, {"type": "petsc"}, a.repeats, ranks, threads)
            r.update(solver="petsc", cells=a.ranks_cells, ranks=ranks, threads=threads, scaling=True)
            rows.append(r)
            print(json.dumps(r), flush=True)
    # The iterative solve's error against the factorization on the same grid.
    for r in rows:
        if r["solver"] == "petsc" and "dofs" in r:
            ref = next((c for c in rows if c["solver"] == "cholmod" and c["cells"] == r["cells"] and "dofs" in c), None)
            if ref:
                r["potential_vs_cholmod"] = rel(r["potential"], ref["potential"])
                r["max_displacement_vs_cholmod"] = rel(r["max_displacement"], ref["max_displacement"])
                r["max_von_mises_vs_cholmod"] = rel(r["max_von_mises"], ref["max_von_mises"])
    with open(os.path.join(a.out, "xfem_scale.json"), "w") as f:
        json.dump(rows, f, indent=1)
    chart([r for r in rows if not r.get("scaling")], os.path.join(a.out, "xfem_scale.png"))
    print("| cells | solver | ranks | unknowns | cut cells | cut+rules s | assemble s | solve s | total s | peak MB | iterations | potential vs CHOLMOD |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|")
    for r in rows:
        if "dofs" not in r:
            print(f"| {r['cells']} | {r['solver']} | {r['ranks']} | failed: {r.get('error', '')[:80]} |")
            continue
        pv = r.get("potential_vs_cholmod")
        print(f"| {r['cells']} | {r['solver']} | {r['ranks']}x{r.get('threads', 2)} | {r['dofs']:,} | {r['cut_cells']:,} | "
              f"{r['cut'] + r['rules']:.2f} | {r['assemble']:.2f} | {r['solve']:.2f} | {r['total']:.2f} | "
              f"{r['peak_mb']:.0f} | {r['iterations']} | {'' if pv is None else f'{pv:.1e}'} |")


if __name__ == "__main__":
    main()
