"""The threaded XFEM simulator (issue 11 §3): speed-up from 1 to 2 threads per phase, and how
time and peak memory grow with the unknowns.

(a) Speed-up: the L-bracket job (samples/simulations/l_bracket.json) at two grids, run by the
    CLI (`parafab simulate --threads N -o DIR`) with 1 and 2 threads alternately in the same
    run; medians over repeats of every phase the result reports (cut, rules, assemble, solve,
    results, write) and of the wall time. From the 2-thread speed-up S2 of a phase, Amdahl's
    law gives its parallel fraction p = 2 (1 − 1/S2) and the speed-up on 16 cores
    1 / ((1 − p) + p/16) (an upper bound: memory bandwidth and OCCT's serial parts aside).
(b) Scale: the same job on grids from a few cells to the largest that runs within
    --max-seconds (and the memory estimate), every size in its own child process: phase
    times, wall time and the child's peak resident memory (os.wait4 → ru_maxrss). The growth
    exponents of time against unknowns (least squares in log–log over the sizes with at
    least --fit-min-dofs unknowns) say whether cut, rules and assembly grow linearly.

Writes DIR/xfem_parallel.json and DIR/xfem_parallel.png (--element hex27: xfem_parallel_hex27.*).
Usage: /usr/bin/python3 tests/bench/bench_xfem_parallel.py [--quick] [--element hex8|hex27] [--out DIR] [--cli PATH]
"""
import argparse
import json
import math
import os
import subprocess
import sys
import tempfile
import time

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.abspath(os.path.join(HERE, "..", ".."))
PART = os.path.join(REPO, "samples", "parts", "l_bracket.step")
JOB = os.path.join(REPO, "samples", "simulations", "l_bracket.json")
PHASES = ["cut", "rules", "assemble", "solve", "results", "write"]


def median(v):
    s = sorted(v)
    n = len(s)
    return s[n // 2] if n % 2 else 0.5 * (s[n // 2 - 1] + s[n // 2])


ELEMENT = "hex8"  # --element; hex8 is the element of the first figures in tests/bench/README.md (the default is hex27 since 2026-11-27)


def run_child(cli, cells, threads, out_dir):
    """One CLI run in a child process: (result JSON, wall seconds, peak RSS in MB); the
    child's CPU time (user + system) is added to the result as "cpu_seconds"."""
    job = json.load(open(JOB))
    job["grid"] = {"cells": cells}
    job["element"] = ELEMENT
    with tempfile.NamedTemporaryFile("w", suffix=".json", delete=False) as f:
        json.dump(job, f)
    try:
        args = [cli, "simulate", PART, f.name, "-o", out_dir]
        if threads:
            args += ["--threads", str(threads)]
        t0 = time.perf_counter()
        with tempfile.TemporaryFile("w+") as stdout:
            p = subprocess.Popen(args, stdout=stdout, stderr=subprocess.DEVNULL)
            _, status, usage = os.wait4(p.pid, 0)
            wall = time.perf_counter() - t0
            p.returncode = os.waitstatus_to_exitcode(status)
            stdout.seek(0)
            text = stdout.read()
        result = json.loads(text)
        result["cpu_seconds"] = usage.ru_utime + usage.ru_stime
        if p.returncode != 0:
            raise RuntimeError(f"{cells} cells, {threads} threads: {result}")
        return result, wall, usage.ru_maxrss / 1024.0
    finally:
        os.unlink(f.name)


def speedup(cli, grids, repeats):
    rows = []
    for cells in grids:
        times = {1: [], 2: []}
        for _ in range(repeats):
            for threads in (1, 2):  # alternate, so load changes hit both alike
                with tempfile.TemporaryDirectory() as d:
                    r, wall, _ = run_child(cli, cells, threads, d)
                times[threads].append(dict(r["seconds"], wall=wall, cpu=r["cpu_seconds"]))
                dofs = r["dofs"]
        row = {"cells": cells, "dofs": dofs, "repeats": repeats, "phases": {}}
        for phase in PHASES + ["wall"]:
            t1 = median([t.get(phase, 0.0) for t in times[1]])
            t2 = median([t.get(phase, 0.0) for t in times[2]])
            s2 = t1 / t2 if t2 > 0 else float("nan")
            p = min(max(2 * (1 - 1 / s2), 0.0), 1.0) if s2 == s2 else float("nan")
            s16 = 1 / ((1 - p) + p / 16) if p == p else float("nan")
            row["phases"][phase] = {"t1": t1, "t2": t2, "speedup2": s2, "parallel_fraction": p, "speedup16": s16}
        # The whole run on 16 cores: every phase with its own parallel fraction.
        t16 = sum(row["phases"][ph]["t1"] / row["phases"][ph]["speedup16"] for ph in PHASES
                  if row["phases"][ph]["t1"] > 0)
        row["run16"] = {"seconds": t16, "speedup": sum(row["phases"][ph]["t1"] for ph in PHASES) / t16}
        # CPU time over wall time: about the thread count on an idle machine; far below it when
        # other processes share the cores (then the speed-ups above say little).
        row["cpu_share"] = {t: median([x["cpu"] / x["wall"] for x in times[t]]) for t in (1, 2)}
        rows.append(row)
        print(f"cpu share {row['cpu_share']}; {cells} cells, {dofs} dofs: " + ", ".join(
            f"{ph} {row['phases'][ph]['t1']:.3f}/{row['phases'][ph]['t2']:.3f}s ({row['phases'][ph]['speedup2']:.2f}x)"
            for ph in PHASES + ["wall"]), flush=True)
    return rows


def fit_exponent(xs, ys):
    pts = [(math.log(x), math.log(y)) for x, y in zip(xs, ys) if x > 0 and y > 0]
    if len(pts) < 2:
        return None
    mx = sum(p[0] for p in pts) / len(pts)
    my = sum(p[1] for p in pts) / len(pts)
    sxx = sum((p[0] - mx) ** 2 for p in pts)
    return sum((p[0] - mx) * (p[1] - my) for p in pts) / sxx if sxx > 0 else None


def scale(cli, grids, max_seconds, fit_min_dofs, threads):
    rows = []
    stopped = "all grids run"
    for cells in grids:
        with tempfile.TemporaryDirectory() as d:
            try:
                r, wall, rss = run_child(cli, cells, threads, d)
            except RuntimeError as e:  # e.g. refused by the memory estimate
                stopped = str(e)
                print("scale: stopped:", stopped, flush=True)
                break
        row = {"cells": cells, "dofs": r["dofs"], "wall": wall, "peak_mb": rss, "cpu": r["cpu_seconds"],
               "seconds": {ph: r["seconds"].get(ph, 0.0) for ph in PHASES},
               "cut_cells": r["grid"]["cut_cells"], "interior_cells": r["grid"]["interior_cells"],
               # CHOLMOD's factor and the estimate before the run (peak: thin-walled to compact figure)
               "factor_mb": r["solver"].get("factor_mb"), "estimate": r.get("estimate")}
        rows.append(row)
        est = r.get("estimate") or {}
        if "peak_mb" in est:
            print(f"scale: {cells} cells: estimated {est['unknowns']:.0f} unknowns, peak {est['peak_mb_min']:.0f}-"
                  f"{est['peak_mb']:.0f} MB; CHOLMOD's factor {row['factor_mb']:.0f} MB", flush=True)
        print(f"scale: {cells} cells, {r['dofs']} dofs, {wall:.2f} s (cpu {r['cpu_seconds']:.2f} s), {rss:.0f} MB: " +
              ", ".join(f"{ph} {row['seconds'][ph]:.3f}" for ph in PHASES), flush=True)
        if wall > max_seconds:
            stopped = f"{cells} cells took {wall:.0f} s > --max-seconds"
            break
    fit = [row for row in rows if row["dofs"] >= fit_min_dofs]
    exponents = {ph: fit_exponent([r["dofs"] for r in fit], [r["seconds"][ph] for r in fit]) for ph in PHASES}
    exponents["wall"] = fit_exponent([r["dofs"] for r in fit], [r["wall"] for r in fit])
    exponents["cpu"] = fit_exponent([r["dofs"] for r in fit], [r["cpu"] for r in fit])
    exponents["peak_mb"] = fit_exponent([r["dofs"] for r in fit], [r["peak_mb"] for r in fit])
    # Cut cells grow like the surface (n^(2/3) of the unknowns): cut and rules per cut cell.
    exponents["cut_cells"] = fit_exponent([r["dofs"] for r in fit], [r["cut_cells"] for r in fit])
    return {"rows": rows, "exponents": exponents, "fit_min_dofs": fit_min_dofs, "stopped": stopped}


def plot(data, path):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, (a, b, c) = plt.subplots(1, 3, figsize=(17, 5))
    width = 0.8 / max(1, len(data["speedup"]))
    for i, row in enumerate(data["speedup"]):
        xs = [k + i * width for k in range(len(PHASES) + 1)]
        a.bar(xs, [row["phases"][ph]["speedup2"] for ph in PHASES + ["wall"]], width,
              label=f"{row['cells']} cells, {row['dofs']} DOFs")
    a.axhline(1, color="k", lw=0.5)
    a.axhline(2, color="gray", lw=0.5, ls="--")
    a.set_xticks([k + 0.4 - width / 2 for k in range(len(PHASES) + 1)])
    a.set_xticklabels(PHASES + ["wall"])
    a.set_ylabel("speed-up 1 → 2 threads (median)")
    a.set_title("Threads: speed-up per phase (%s)" % data.get("element", "hex8"))
    a.legend(fontsize=8)
    rows = data["scale"]["rows"]
    dofs = [r["dofs"] for r in rows]
    for ph in PHASES:
        e = data["scale"]["exponents"].get(ph)
        b.loglog(dofs, [max(r["seconds"][ph], 1e-4) for r in rows], "o-",
                 label=f"{ph} (∝ n^{e:.2f})" if e is not None else ph)
    b.loglog(dofs, [r["wall"] for r in rows], "k--", label="wall")
    if dofs:
        ref = [dofs[0] * 2 ** k for k in range(int(math.log2(max(dofs) / dofs[0])) + 2)]
        y0 = rows[0]["wall"]
        b.loglog(ref, [y0 * x / dofs[0] for x in ref], ":", color="gray", label="∝ n")
    b.set_xlabel("unknowns (DOFs)")
    b.set_ylabel("seconds")
    b.set_title("Scale: time per phase")
    b.legend(fontsize=7)
    c.loglog(dofs, [r["peak_mb"] for r in rows], "o-", label="measured peak (whole run)")
    with_est = [r for r in rows if (r.get("estimate") or {}).get("peak_mb")]
    if with_est:
        d = [r["dofs"] for r in with_est]
        c.fill_between(d, [r["estimate"]["peak_mb_min"] for r in with_est], [r["estimate"]["peak_mb"] for r in with_est],
                       color="C1", alpha=0.25, label="estimate before the run (thin-walled … compact)")
        c.loglog(d, [r["factor_mb"] for r in with_est], "s:", color="C2", label="CHOLMOD's factor (exact)")
    c.legend(fontsize=7)
    c.set_xlabel("unknowns (DOFs)")
    c.set_ylabel("peak resident memory [MB]")
    e = data["scale"]["exponents"].get("peak_mb")
    c.set_title(f"Scale: peak memory (∝ n^{e:.2f})" if e is not None else "Scale: peak memory")
    fig.tight_layout()
    fig.savefig(path, dpi=110)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--quick", action="store_true", help="smoke run: small grids, one repeat")
    ap.add_argument("--out", default="out/bench")
    ap.add_argument("--cli", default=os.environ.get("PARAFAB_CLI", os.path.join(REPO, "build", "workbench", "entry", "parafab")))
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--speedup-grids", default="24,40")
    ap.add_argument("--scale-grids", default="6,8,12,16,24,32,48,64,80,96")
    ap.add_argument("--max-seconds", type=float, default=180, help="stop the scale sweep after a run this long")
    ap.add_argument("--fit-min-dofs", type=float, default=5000)
    ap.add_argument("--scale-threads", type=int, default=0, help="threads of the scale runs (0: all cores)")
    ap.add_argument("--element", default="hex8", choices=["hex8", "hex27"],
                    help="element of every run; hex27 writes xfem_parallel_hex27.json / .png")
    args = ap.parse_args()
    global ELEMENT
    ELEMENT = args.element
    name = "xfem_parallel" + ("" if args.element == "hex8" else "_" + args.element)
    if args.quick:
        args.repeats, args.speedup_grids, args.scale_grids, args.fit_min_dofs = 1, "6", "4,6,8", 0
    os.makedirs(args.out, exist_ok=True)
    grids = [int(x) for x in args.speedup_grids.split(",")]
    data = {"machine": {"cpus": os.cpu_count()}, "date": time.strftime("%Y-%m-%d %H:%M"), "element": args.element,
            "speedup": speedup(args.cli, grids, args.repeats),
            "scale": scale(args.cli, [int(x) for x in args.scale_grids.split(",")], args.max_seconds,
                           args.fit_min_dofs, args.scale_threads)}
    print("exponents:", json.dumps(data["scale"]["exponents"]))
    with open(os.path.join(args.out, name + ".json"), "w") as f:
        json.dump(data, f, indent=2)
    plot(data, os.path.join(args.out, name + ".png"))


if __name__ == "__main__":
    main()
