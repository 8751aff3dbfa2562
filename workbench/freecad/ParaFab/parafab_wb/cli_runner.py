"""Run ``parafab simulate`` in a separate process (QProcess) for the task panel.

* :func:`find_cli` locates the ``parafab`` executable: ``$PARAFAB_CLI``, then beside the
  installed ``parafab`` Python module, then in the workbench folder, then on ``PATH``.
* :class:`SimulationProcess` runs ``parafab simulate PART JOB -o OUTDIR --progress``, turns
  the JSON lines on stderr into ``progress(phase, fraction)`` signals and the end of the process
  into one ``done(Outcome)`` signal: solved (the result JSON from stdout), error (the CLI's JSON
  error, exit status 2, or a crash) or cancelled (:meth:`SimulationProcess.cancel` kills it).
* :class:`AnalysisRun` prepares the files for an ``Analysis`` feature and records the outcome
  in it with :func:`analysis_feature.apply_run`: only a solved run changes the document.

Only ``QtCore`` is used, so this works in ``freecadcmd`` too (with a ``QCoreApplication``).
"""

import json
import os
import shutil
import tempfile

from PySide import QtCore

from . import analysis_feature

CLI_NAME = "parafab"
SOLVED, ERROR, CANCELLED = "solved", "error", analysis_feature.CANCELLED


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


class Outcome(object):
    """How a run ended: ``state`` is SOLVED, ERROR or CANCELLED."""

    def __init__(self, state, result=None, message=""):
        self.state = state
        self.result = result
        self.message = message

    def __repr__(self):
        return "Outcome(%r, %r)" % (self.state, self.message)


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


class SimulationProcess(QtCore.QObject):
    """One ``parafab simulate --progress`` process."""

    progress = QtCore.Signal(str, float)
    done = QtCore.Signal(object)

    #: The subcommand run and the text of a cancelled run (subclasses run other subcommands).
    SUBCOMMAND = "simulate"
    CANCEL_MESSAGE = "simulation cancelled by the user"

    def __init__(self, parent=None):
        super(SimulationProcess, self).__init__(parent)
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


class AnalysisRun(QtCore.QObject):
    """Run ``inputs`` of an ``Analysis`` feature through the CLI and record the outcome.

    ``progress(phase, fraction)`` and ``done(Outcome)`` are re-emitted from the process; when
    ``done`` fires, the outcome has already been stored by :func:`analysis_feature.apply_run`.
    """

    progress = QtCore.Signal(str, float)
    done = QtCore.Signal(object)

    def __init__(self, analysis, inputs, cli=None, parent=None):
        super(AnalysisRun, self).__init__(parent)
        self.analysis = analysis
        self.inputs = dict(inputs)
        self.cli = cli or find_cli()
        self.out_dir = analysis_feature.output_dir(analysis, self.inputs)
        self.process = None
        self.outcome = None
        self._tmp = None

    def start(self):
        """Check the inputs, write the part and job files, start the CLI. Input errors end the
        run at once (``done`` with ERROR)."""
        try:
            if not self.cli:
                raise analysis_feature.AnalysisError(
                    "the parafab executable was not found (set PARAFAB_CLI, or install it beside the workbench)")
            job = analysis_feature.job_from_inputs(self.analysis.Part, self.inputs)
            os.makedirs(self.out_dir, exist_ok=True)
            self._tmp = tempfile.mkdtemp(prefix="parafab_run_")
            part = os.path.join(self._tmp, "part.brep")
            self.analysis.Part.Shape.exportBrep(part)
            job_path = os.path.join(self._tmp, "job.json")
            with open(job_path, "w") as f:
                json.dump(job, f, indent=1)
        except Exception as exc:
            self._done(Outcome(ERROR, message=str(exc) or type(exc).__name__))
            return
        self.process = SimulationProcess(self)
        self.process.progress.connect(self.progress)
        self.process.done.connect(self._done)
        self.process.start(self.cli, part, job_path, self.out_dir)

    def running(self):
        return self.process is not None and self.process.running()

    def cancel(self):
        if self.process is not None:
            self.process.cancel()

    def _done(self, outcome):
        if self._tmp:
            shutil.rmtree(self._tmp, ignore_errors=True)
            self._tmp = None
        try:
            analysis_feature.apply_run(self.analysis, self.inputs, outcome.state, outcome.result,
                                       self.out_dir, outcome.message)
        except Exception as exc:  # e.g. a malformed surface.vtu
            outcome = Outcome(ERROR, result=outcome.result, message="cannot show the result: %s" % exc)
            analysis_feature.apply_run(self.analysis, self.inputs, ERROR, message=outcome.message)
        self.outcome = outcome
        self.done.emit(outcome)


def run_blocking(run, timeout_ms=300000, on_progress=None):
    """Start ``run`` (an :class:`AnalysisRun`) and wait in a local event loop until it ends;
    returns its Outcome (for scripts and tests)."""
    loop = QtCore.QEventLoop()
    run.done.connect(lambda outcome: loop.quit())
    if on_progress is not None:
        run.progress.connect(on_progress)
    QtCore.QTimer.singleShot(timeout_ms, loop.quit)
    QtCore.QTimer.singleShot(0, run.start)
    loop.exec_()
    if run.outcome is None:
        run.cancel()
        if run.process is not None and run.process.process is not None:
            run.process.process.waitForFinished(5000)
    return run.outcome
