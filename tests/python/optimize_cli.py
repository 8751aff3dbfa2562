"""Shared by the optimize tests: run `parafab optimize` (or `simulate`) on a job through the CLI
(a temporary job file) and return its exit code with its JSON output or error message."""
import json
import os
import subprocess
import tempfile

CLI = os.environ.get("PARAFAB_CLI", "build/workbench/entry/parafab")


def optimize_cli_error(part, job):
    """(exit code, error message or None) of `parafab optimize PART JOB -o TMP`."""
    with tempfile.NamedTemporaryFile("w", suffix=".json", delete=False) as f:
        json.dump(job, f)
    try:
        p = subprocess.run([CLI, "optimize", part, f.name, "-o", tempfile.mkdtemp()], capture_output=True, text=True)
    finally:
        os.unlink(f.name)
    try:
        message = json.loads(p.stdout)["error"]["message"]
    except (ValueError, KeyError, TypeError):
        message = None
    return p.returncode, message


def cli(args, job):
    """(exit code, JSON output) of `parafab ARGS[0] ARGS[1] JOB ARGS[2:]`, e.g.
    cli(["optimize", part, "-o", out], job) or cli(["simulate", part], job)."""
    with tempfile.NamedTemporaryFile("w", suffix=".json", delete=False) as f:
        json.dump(job, f)
    try:
        p = subprocess.run([CLI] + args[:1] + [args[1], f.name] + args[2:], capture_output=True, text=True, timeout=600)
        return p.returncode, json.loads(p.stdout)
    finally:
        os.unlink(f.name)
