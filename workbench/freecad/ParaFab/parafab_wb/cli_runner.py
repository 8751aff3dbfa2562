"""Run the ``parafab`` CLI in a separate process (QProcess): the run objects of the task panels.

* :func:`find_cli` locates the ``parafab`` executable: ``$PARAFAB_CLI``, then beside the
  installed ``parafab`` Python module, then in the workbench folder, then on ``PATH``.
* :class:`CliProcess` runs ``parafab SUBCOMMAND PART JOB -o OUTDIR --progress``, turns the JSON
  lines on stderr into ``progress(phase, fraction)`` signals and the end of the process into one
  ``done(Outcome)`` signal: solved (the result JSON from stdout), error (the CLI's JSON error,
  exit status 2, or a crash) or cancelled (:meth:`CliProcess.cancel`). A subcommand overrides
  what differs: :class:`SimulationProcess` (``simulate``: cancel kills it) here,
  ``optimize_runner.OptimizeProcess`` (``optimize``: cancel asks it to stop with SIGTERM).
* :class:`CliRun` is one run for a task panel: it writes the part and job files
  (:meth:`CliRun.prepare`), starts the process and records the outcome (:meth:`CliRun.record`)
  before it re-emits ``done``. :class:`AnalysisRun` here runs an ``Analysis`` feature's inputs
  and records them with :func:`analysis_job.apply_run` (only a solved run changes the document);
  ``optimize_runner.OptimizeRun`` adds the optimized solid.

Outcomes are :class:`outcome.Outcome` (re-exported here with SOLVED, ERROR and CANCELLED).
Only ``QtCore`` is used, so this works in ``freecadcmd`` too (with a ``QCoreApplication``).
"""

import json
import os
import shutil
import tempfile

from PySide import QtCore

from . import analysis_job
from .outcome import CANCELLED, ERROR, SOLVED, Outcome  # noqa: F401  (re-exported)

CLI_NAME = "parafab"
NOT_FOUND = "the parafab executable was not found (set PARAFAB_CLI, or install it beside the workbench)"


def _executable(path):
    return bool(path) and os.path.isfile(path) and os.access(path, os.X_OK)


def find_cli():
    """Absolute path of the ``parafab`` executable, or ``None``."""
    env = os.environ.get("PARAFAB_CLI")
    if env:
        return os.path.abspath(env) if _executable(env) else None
    candidates = []
    try:
        import parafab
        module_file = getattr(parafab, "__file__", None)
        if module_file:
            candidates.append(os.path.join(os.path.dirname(os.path.abspath(module_file)), CLI_NAME))
    except ImportError:
        pass
    wb_dir = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))  # <Mod>/ParaFab
    candidates.append(os.path.join(wb_dir, CLI_NAME))
    for path in candidates:
        if _executable(path):
            return path
    return shutil.which(CLI_NAME)


def parse_progress(line):
    """``(phase, fraction)`` of a ``--progress`` line, or ``None`` for other output."""
    try:
        data = json.loads(line)
        p = data["progress"]
        return str(p["phase"]), float(p["fraction"])
    except (ValueError, KeyError, TypeError):
        return None


def parse_output(exit_code, stdout):
    """Outcome of a finished CLI run from its exit code and standard output."""
    text = stdout.strip()
    try:
        data = json.loads(text) if text else None
    except ValueError:
        data = None
    if isinstance(data, dict) and "error" in data:
        err = data["error"]
        message = err.get("message", str(err)) if isinstance(err, dict) else str(err)
        return Outcome(ERROR, message=message)
    if exit_code == 0 and isinstance(data, dict):
        return Outcome(SOLVED, result=data)
    return Outcome(ERROR, message="parafab exited with status %d%s" % (exit_code, (": " + text[-500:]) if text else ""))


class CliProcess(QtCore.QObject):
    """One ``parafab SUBCOMMAND PART JOB -o OUTDIR --progress`` process; subclasses set the
    subcommand and override what differs (:meth:`cancel`, :meth:`parse_progress`,
    :meth:`cancelled_outcome`)."""

    progress = QtCore.Signal(str, float)
    done = QtCore.Signal(object)

    #: The subcommand run and the text of a cancelled run.
    SUBCOMMAND = ""
    CANCEL_MESSAGE = "cancelled by the user"

    def __init__(self, parent=None):
        super(CliProcess, self).__init__(parent)
        self.process = None
        self.cancelled = False
        self.finished = False
        self._stderr = b""
        self._other_stderr = []

    def start(self, cli, part, job, out_dir):
        """Start the process; ``done`` is emitted when it ends (also when it cannot start)."""
        self.process = QtCore.QProcess(self)
        self.process.readyReadStandardError.connect(self._read_stderr)
        self.process.finished.connect(self._finished)
        self.process.errorOccurred.connect(self._error)
        self.process.start(cli, [self.SUBCOMMAND, part, job, "-o", out_dir, "--progress"])

    def running(self):
        return self.process is not None and self.process.state() != QtCore.QProcess.NotRunning

    def wait(self, msecs):
        """Block until the process has ended (at most ``msecs``)."""
        if self.process is not None:
            self.process.waitForFinished(msecs)

    def cancel(self):
        """Kill the process; ``done`` then reports CANCELLED."""
        if self.running():
            self.cancelled = True
            self.process.kill()

    def _read_stderr(self):
        self._stderr += bytes(self.process.readAllStandardError())
        *lines, self._stderr = self._stderr.split(b"\n")
        for raw in lines:
            line = raw.decode("utf-8", "replace").strip()
            if not line:
                continue
            parsed = self.parse_progress(line)
            if parsed is None:
                self._other_stderr.append(line)
            else:
                self.progress.emit(*parsed)

    def parse_progress(self, line):
        """``(phase, fraction)`` of a stderr line, or ``None`` for other output."""
        return parse_progress(line)

    def cancelled_outcome(self, exit_code, stdout):
        """The Outcome of a cancelled run (the process killed: nothing to read)."""
        return Outcome(CANCELLED, message=self.CANCEL_MESSAGE)

    def _error(self, error):
        if error == QtCore.QProcess.FailedToStart and not self.finished:
            self.finished = True
            self.done.emit(Outcome(ERROR, message="cannot start %s: %s"
                                   % (self.process.program(), self.process.errorString())))

    def _finished(self, exit_code, exit_status=None):
        if self.finished:
            return
        self.finished = True
        self._read_stderr()
        stdout = bytes(self.process.readAllStandardOutput()).decode("utf-8", "replace")
        if self.cancelled:
            outcome = self.cancelled_outcome(exit_code, stdout)
        elif exit_status == QtCore.QProcess.CrashExit:
            outcome = Outcome(ERROR, message="parafab crashed%s" % (
                ": " + " ".join(self._other_stderr[-3:]) if self._other_stderr else ""))
        else:
            outcome = parse_output(exit_code, stdout)
        self.done.emit(outcome)


class SimulationProcess(CliProcess):
    """One ``parafab simulate --progress`` process (cancel kills it)."""

    SUBCOMMAND = "simulate"
    CANCEL_MESSAGE = "simulation cancelled by the user"


class CliRun(QtCore.QObject):
    """One run of the CLI for a task panel: :meth:`prepare` the files, run :meth:`make_process`,
    :meth:`record` the outcome (then ``outcome`` is set and ``done(Outcome)`` emitted).

    ``progress(phase, fraction)`` is re-emitted from the process. Errors before the process
    starts (no CLI, bad input) end the run at once with ERROR. Subclasses implement
    :meth:`prepare` and override :meth:`make_process` and :meth:`record`.
    """

    progress = QtCore.Signal(str, float)
    done = QtCore.Signal(object)

    def __init__(self, cli=None, parent=None):
        super(CliRun, self).__init__(parent)
        self.cli = cli or find_cli()
        self.process = None
        self.outcome = None

    def prepare(self):
        """Check the inputs and write the files; returns ``(part, job, job_path, out_dir)``
        (``job``: the job as a dict). Raises on bad input."""
        raise NotImplementedError

    def make_process(self, job):
        """The :class:`CliProcess` that runs ``job``."""
        return SimulationProcess(self)

    def record(self, outcome):
        """Put ``outcome`` into the document; returns the outcome to report (ERROR when
        recording failed)."""
        return outcome

    def start(self):
        """Prepare and start the CLI; ``done`` is emitted when the run has ended."""
        try:
            if not self.cli:
                raise RuntimeError(NOT_FOUND)
            part, job, job_path, out_dir = self.prepare()
        except Exception as exc:
            self._done(Outcome(ERROR, message=str(exc) or type(exc).__name__))
            return
        self.process = self.make_process(job)
        self.process.progress.connect(self.progress)
        self.process.done.connect(self._done)
        self.process.start(self.cli, part, job_path, out_dir)

    def running(self):
        return self.process is not None and self.process.running()

    def cancel(self):
        if self.process is not None:
            self.process.cancel()

    def wait(self, msecs):
        """Block until the process has ended (at most ``msecs``); its ``done`` comes with the
        next event processing."""
        if self.process is not None:
            self.process.wait(msecs)

    def cleanup(self):
        """Remove temporary files (called once the run has ended)."""

    def _done(self, outcome):
        self.cleanup()
        self.outcome = self.record(outcome)
        self.done.emit(self.outcome)


class AnalysisRun(CliRun):
    """Run ``inputs`` of an ``Analysis`` feature through ``parafab simulate`` and record the
    outcome: when ``done`` fires, it has been stored by :func:`analysis_job.apply_run`."""

    def __init__(self, analysis, inputs, cli=None, parent=None):
        super(AnalysisRun, self).__init__(cli, parent)
        self.analysis = analysis
        self.inputs = dict(inputs)
        self.out_dir = analysis_job.output_dir(analysis, self.inputs)
        self._tmp = None

    def prepare(self):
        job = analysis_job.job_from_inputs(self.analysis.Part, self.inputs)
        os.makedirs(self.out_dir, exist_ok=True)
        self._tmp = tempfile.mkdtemp(prefix="parafab_run_")
        part = os.path.join(self._tmp, "part.brep")
        self.analysis.Part.Shape.exportBrep(part)
        job_path = os.path.join(self._tmp, "job.json")
        with open(job_path, "w") as f:
            json.dump(job, f, indent=1)
        return part, job, job_path, self.out_dir

    def cleanup(self):
        if self._tmp:
            shutil.rmtree(self._tmp, ignore_errors=True)
            self._tmp = None

    def record(self, outcome):
        try:
            analysis_job.apply_run(self.analysis, self.inputs, outcome, self.out_dir)
        except Exception as exc:  # e.g. a malformed surface.vtu
            outcome = Outcome(ERROR, result=outcome.result, message="cannot show the result: %s" % exc)
            analysis_job.apply_run(self.analysis, self.inputs, outcome)
        return outcome


def run_blocking(run, timeout_ms=300000, on_progress=None):
    """Start ``run`` (a :class:`CliRun`) and wait in a local event loop until it ends; returns
    its Outcome (for scripts and tests; ``None`` after ``timeout_ms``, the run then cancelled)."""
    loop = QtCore.QEventLoop()
    run.done.connect(lambda outcome: loop.quit())
    if on_progress is not None:
        run.progress.connect(on_progress)
    QtCore.QTimer.singleShot(timeout_ms, loop.quit)
    QtCore.QTimer.singleShot(0, run.start)
    loop.exec_()
    if run.outcome is None:
        run.cancel()
        run.wait(5000)
    return run.outcome
