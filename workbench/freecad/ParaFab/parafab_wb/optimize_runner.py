"""Run ``parafab optimize`` in a separate process (QProcess) for the "Optimize shape" panel.

The optimize-specific parts of the run objects of :mod:`parafab_wb.cli_runner`:
:class:`OptimizeRun` (a ``cli_runner.CliRun``) writes the part and job
(:func:`optimize_feature.prepare`), runs ``parafab optimize PART JOB -o OUTDIR --progress``
(:class:`OptimizeProcess`, a ``cli_runner.CliProcess``; one JSON line
``{"progress": {iteration, objective, ...}}`` per iterate on stderr), and when the process ends
adds the optimized solid beside the original (:func:`optimize_feature.add_result`). Cancel sends
SIGTERM once: the CLI stops at its next evaluation and writes its best valid iterate so far into
the output folder (``optimized.step``, ``history.json`` with status "interrupted"; killed if it
has not ended within :attr:`OptimizeProcess.KILL_AFTER_MS`); nothing is added to the document.
Errors (bad input, the CLI's JSON error, an invalid result) only set the outcome's message.

Only ``QtCore`` is used, so this works in ``freecadcmd`` too (with a ``QCoreApplication``).
"""

import json

from PySide import QtCore

from . import cli_runner
from . import optimize_feature

SOLVED, ERROR, CANCELLED = cli_runner.SOLVED, cli_runner.ERROR, cli_runner.CANCELLED


class OptimizeProcess(cli_runner.CliProcess):
    """One ``parafab optimize --progress`` process; ``iterate(dict)`` per optimizer iterate."""

    SUBCOMMAND = "optimize"
    CANCEL_MESSAGE = "optimization cancelled by the user"
    #: After Cancel, how long the CLI may take to write its best iterate before it is killed.
    KILL_AFTER_MS = 30000
    iterate = QtCore.Signal(object)

    def cancel(self):
        """Ask the CLI to stop (SIGTERM); it writes the best valid iterate so far and exits. Only
        once: a second SIGTERM would kill it before it has written (the CLI's own rule)."""
        if self.running() and not self.cancelled:
            self.cancelled = True
            self.process.terminate()
            QtCore.QTimer.singleShot(self.KILL_AFTER_MS, self._kill_if_running)

    def _kill_if_running(self):
        if self.running():
            self.process.kill()

    def cancelled_outcome(self, exit_code, stdout):
        """CANCELLED, with the interrupted run's history (status "interrupted") when the CLI wrote
        one, and a message saying where its best iterate is."""
        try:
            history = json.loads(stdout)
        except ValueError:
            history = None
        if isinstance(history, dict) and history.get("status") == optimize_feature.INTERRUPTED \
                and history.get("optimized_step"):
            return cli_runner.Outcome(
                CANCELLED, result=history,
                message="%s after %d iterates; the best valid one so far is %s (not added)"
                        % (self.CANCEL_MESSAGE, max(len(history.get("iterations", [])) - 1, 0),
                           history["optimized_step"]))
        return cli_runner.Outcome(CANCELLED, message=self.CANCEL_MESSAGE)

    def __init__(self, max_iterations, parent=None):
        super(OptimizeProcess, self).__init__(parent)
        self.max_iterations = max(int(max_iterations), 1)
        self.iterates = []

    def parse_progress(self, line):
        try:
            it = json.loads(line)["progress"]
            k = int(it["iteration"])
            f = float(it["objective"])
        except (ValueError, KeyError, TypeError):
            return None
        self.iterates.append(it)
        self.iterate.emit(it)
        return "iteration %d: objective %.4g" % (k, f), min(1.0, k / float(self.max_iterations))


class OptimizeRun(cli_runner.CliRun):
    """Optimize ``obj`` with panel ``options`` through the CLI; on success ``result_object`` is
    the new solid and ``history`` the run's history. ``iterate(dict)`` per optimizer iterate."""

    iterate = QtCore.Signal(object)

    def __init__(self, obj, options, out_dir=None, cli=None, parent=None):
        super(OptimizeRun, self).__init__(cli, parent)
        self.obj = obj
        self.options = dict(options)
        self.out_dir = out_dir
        self.history = None
        self.result_object = None
        self._placement = None

    def prepare(self):
        part, job, job_path, self.out_dir, self._placement = optimize_feature.prepare(
            self.obj, self.options, self.out_dir)
        return part, job, job_path, self.out_dir

    def make_process(self, job):
        process = OptimizeProcess(job.get("max_iterations", 20), self)
        process.iterate.connect(self.iterate)
        return process

    def record(self, outcome):
        if outcome.state == SOLVED:
            self.history = outcome.result
            try:
                self.result_object = optimize_feature.add_result(self.obj, self.history, self.out_dir,
                                                                 self._placement)
            except Exception as exc:
                outcome = cli_runner.Outcome(ERROR, result=outcome.result, message=str(exc))
        return outcome


def run_blocking(run, timeout_ms=300000, on_progress=None):
    """Start ``run`` and wait in a local event loop until it ends; returns its Outcome."""
    return cli_runner.run_blocking(run, timeout_ms, on_progress)
