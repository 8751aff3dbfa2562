"""The base of the task panels that run the ``parafab`` CLI ("Analyze part", "Optimize shape"),
and the widgets they share (GUI only).

:class:`RunTaskPanel` holds what both panels do alike: the undo transaction they work in, the
**Run** / **Cancel run** buttons, the progress bar and the status line, starting a run object
(a :class:`cli_runner.CliRun`) and following its ``progress`` and ``done`` signals, stopping a
run when the panel closes, OK (keep) and Cancel (undo). A panel sets its title, icon and
transaction name and overrides the small parts that differ: :meth:`~RunTaskPanel.make_run`,
:meth:`~RunTaskPanel.show_outcome` and optionally :meth:`~RunTaskPanel.run_problem`,
:meth:`~RunTaskPanel.running_text` and :meth:`~RunTaskPanel.closing`.

Shared widgets: :class:`FaceList` (faces picked in the 3D view), :func:`selected_faces`,
:func:`spin`, :func:`wrapped`.
"""

import FreeCAD
import FreeCADGui
from PySide import QtCore, QtGui

from . import icon_path
from .outcome import CANCELLED, SOLVED


def selected_faces(accepted):
    """Face names (``FaceN``) selected in the 3D view on one of the ``accepted`` objects."""
    names = []
    for sel in FreeCADGui.Selection.getSelectionEx():
        if sel.Object not in accepted:
            continue
        for sub in sel.SubElementNames:
            element = sub.split(".")[-1]
            if element.startswith("Face") and element not in names:
                names.append(element)
    return names


def narrow(widget, width=60):
    """Let ``widget`` shrink below its size hint: the combo view is often narrow."""
    widget.setMinimumWidth(width)
    return widget


def spin(lo, hi, value, decimals=3, suffix="", prefix=""):
    """A QDoubleSpinBox from ``lo`` to ``hi`` showing ``value``."""
    box = QtGui.QDoubleSpinBox()
    box.setRange(lo, hi)
    box.setDecimals(decimals)
    box.setValue(value)
    if suffix:
        box.setSuffix(suffix)
    if prefix:
        box.setPrefix(prefix)
    return box


def wrapped(text, tooltip=""):
    """A word-wrapped label."""
    label = QtGui.QLabel(text)
    label.setWordWrap(True)
    if tooltip:
        label.setToolTip(tooltip)
    return label


class FaceList(QtGui.QWidget):
    """A list of faces with "Add selected faces" and "Remove" buttons."""

    def __init__(self, title, faces, accepted, parent=None):
        super(FaceList, self).__init__(parent)
        self.accepted = accepted
        layout = QtGui.QVBoxLayout(self)
        layout.setContentsMargins(0, 0, 0, 0)
        self.title = QtGui.QLabel(title)
        self.title.setWordWrap(True)  # long titles wrap instead of widening the task panel
        layout.addWidget(self.title)
        self.list = QtGui.QListWidget()
        self.list.setSelectionMode(QtGui.QAbstractItemView.ExtendedSelection)
        self.list.setMaximumHeight(80)
        self.list.addItems(list(faces))
        layout.addWidget(self.list)
        buttons = QtGui.QHBoxLayout()
        # Full-size buttons (narrowed, they read "Remov" at the task panel's default width).
        self.add_button = QtGui.QPushButton("Add selected")
        self.add_button.setToolTip("Add selected faces: the faces selected in the 3D view")
        self.remove_button = QtGui.QPushButton("Remove")
        self.remove_button.setToolTip("Remove the faces selected in this list")
        buttons.addWidget(self.add_button)
        buttons.addWidget(self.remove_button)
        layout.addLayout(buttons)
        self.add_button.clicked.connect(self.add_selected)
        self.remove_button.clicked.connect(self.remove)

    def faces(self):
        return [self.list.item(i).text() for i in range(self.list.count())]

    def add_selected(self):
        new = [f for f in selected_faces(self.accepted) if f not in self.faces()]
        if not new:
            FreeCAD.Console.PrintWarning("ParaFab: select faces of %s in the 3D view first\n"
                                         % self.accepted[0].Label)
        self.list.addItems(new)
        return new

    def remove(self):
        for item in self.list.selectedItems():
            self.list.takeItem(self.list.row(item))


class RunTaskPanel(object):
    """A task dialog (``form`` + accept/reject) on document object ``obj`` that runs the CLI.

    Subclasses set :attr:`TITLE`, :attr:`ICON`, :attr:`TRANSACTION`, build ``self.form`` in their
    ``__init__`` (after this one's) with :meth:`add_run_widgets` in it, and implement
    :meth:`make_run` and :meth:`show_outcome`.
    """

    TITLE = ""
    ICON = ""
    #: Name of the undo transaction the panel opens when none is pending.
    TRANSACTION = ""
    #: True: OK commits (Cancel aborts) a transaction that was pending when the panel opened
    #: (the command's, which created the object the panel edits); False: only its own.
    ADOPTS_PENDING_TRANSACTION = False
    #: The progress bar's text while running (``%s``: the phase).
    PROGRESS_FORMAT = "%s %%p%%"
    #: The panel currently shown, per panel class (see :meth:`show`, :meth:`active`).
    _active = None

    def __init__(self, obj):
        self.obj = obj
        self.doc = obj.Document
        self.run = None
        self.outcome = None
        self._own_transaction = False
        if not self.doc.HasPendingTransaction:
            self.doc.openTransaction(self.TRANSACTION)
            self._own_transaction = True

    @classmethod
    def show(cls, *args):
        """Close the open task dialog and show a new panel ``cls(*args)``; returns it."""
        if FreeCADGui.Control.activeDialog():
            FreeCADGui.Control.closeDialog()
        panel = cls(*args)
        cls._active = panel
        FreeCADGui.Control.showDialog(panel)
        return panel

    @classmethod
    def active(cls):
        """The open panel of this class, or ``None``."""
        return cls.__dict__.get("_active")

    def set_window(self, form):
        form.setWindowTitle(self.TITLE)
        form.setWindowIcon(QtGui.QIcon(icon_path(self.ICON)))
        return form

    # -- widgets -----------------------------------------------------------------------------

    def add_run_widgets(self, layout, status="Not run yet"):
        """Add the Run / Cancel run buttons, the progress bar and the status line to ``layout``."""
        buttons = QtGui.QHBoxLayout()
        self.run_button = QtGui.QPushButton("Run")
        self.cancel_button = QtGui.QPushButton("Cancel run")
        self.cancel_button.setEnabled(False)
        buttons.addWidget(self.run_button)
        buttons.addWidget(self.cancel_button)
        layout.addLayout(buttons)
        self.progress = QtGui.QProgressBar()
        self.progress.setRange(0, 100)
        self.progress.setValue(0)
        layout.addWidget(self.progress)
        self.status = wrapped(status)
        self.status.setTextInteractionFlags(QtCore.Qt.TextSelectableByMouse)
        layout.addWidget(self.status)
        self.run_button.clicked.connect(self.start_run)
        self.cancel_button.clicked.connect(self.cancel_run)

    # -- what a panel overrides --------------------------------------------------------------

    def make_run(self):
        """The run object (a :class:`cli_runner.CliRun`, not started) for the panel's inputs."""
        raise NotImplementedError

    def run_problem(self):
        """Why the inputs cannot be run (shown as "Not run: ..."), or ``""``."""
        return ""

    def running_text(self):
        """The status line while a run goes."""
        return "Running…"

    def show_outcome(self, outcome):
        """Show a finished run (the buttons and progress bar are already reset)."""
        raise NotImplementedError

    def closing(self):
        """Called before the dialog closes (after OK or Cancel)."""

    # -- running -----------------------------------------------------------------------------

    def start_run(self):
        """Start a run on the panel's inputs (no-op while one is going); returns whether it started."""
        if self.running():
            return False
        problem = self.run_problem()
        if problem:
            self.status.setText("Not run: %s" % problem)
            return False
        self.outcome = None
        self.progress.setValue(0)
        self.progress.setFormat(self.PROGRESS_FORMAT % "starting")
        self.status.setText(self.running_text())
        self.run_button.setEnabled(False)
        self.cancel_button.setEnabled(True)
        self.run = self.make_run()
        self.run.progress.connect(self._progress)
        self.run.done.connect(self._done)
        self.run.start()
        return True

    def cancel_run(self):
        if self.run is not None:
            self.run.cancel()

    def running(self):
        return self.run is not None and self.run.running()

    def _progress(self, phase, fraction):
        self.progress.setValue(int(round(100 * fraction)))
        self.progress.setFormat(self.PROGRESS_FORMAT % phase)

    def _done(self, outcome):
        self.outcome = outcome
        self.run_button.setEnabled(True)
        self.cancel_button.setEnabled(False)
        if outcome.state == SOLVED:
            self.progress.setValue(100)
            self.progress.setFormat("done")
        else:
            self.progress.setValue(0)
            self.progress.setFormat("cancelled" if outcome.state == CANCELLED else "failed")
        self.show_outcome(outcome)
        FreeCADGui.updateGui()

    # -- task dialog -------------------------------------------------------------------------

    def getStandardButtons(self):
        return int(QtGui.QDialogButtonBox.Ok | QtGui.QDialogButtonBox.Cancel)

    def _stop(self):
        if self.running():
            self.run.cancel()
            self.run.wait(5000)
            QtCore.QCoreApplication.processEvents()

    def _transaction(self):
        return self._own_transaction or self.ADOPTS_PENDING_TRANSACTION

    def _close(self):
        self.closing()
        if type(self).__dict__.get("_active") is self:
            type(self)._active = None
        FreeCADGui.Control.closeDialog()

    def accept(self):
        """OK: keep what the runs did (and commit the undo transaction)."""
        self._stop()
        if self._transaction():
            self.doc.commitTransaction()
        self._close()
        return True

    def reject(self):
        """Cancel: stop a run and undo what was done since the panel opened."""
        self._stop()
        if self._transaction():
            self.doc.abortTransaction()
        self.undo()
        self._close()
        return True

    def undo(self):
        """After Cancel's abortTransaction: remove what undo did not (undo may be off)."""
