"""Run the `parafab` CLI pinned to one core (taskset -c 0) on a job, for the benchmarks that time
iterations on one core (bench_optimize_failure.py, bench_optimize_target.py)."""
import json
import os
import subprocess
import tempfile
import time

CLI = os.environ.get("PARAFAB_CLI", "build/workbench/entry/parafab")


def cli(argv, job):
    """(JSON output, wall seconds) of `parafab ARGV[0] ARGV[1] JOB ARGV[2:]`, e.g.
    cli(["optimize", part, "-o", out], job), on core 0."""
    with tempfile.NamedTemporaryFile("w", suffix=".json", delete=False) as f:
        json.dump(job, f)
    try:
        t = time.time()
        p = subprocess.run(["taskset", "-c", "0", CLI] + argv[:2] + [f.name] + argv[2:], capture_output=True,
                           text=True, timeout=3600)
        return json.loads(p.stdout), time.time() - t
    finally:
        os.unlink(f.name)
