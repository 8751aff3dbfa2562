"""Shared by the optimize tests: run `parafab optimize` on a job through the CLI (a temporary
job file) and return its exit code and the message of its JSON error."""
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
