"""Task panel of the ``Analysis`` feature ("Analyze part", or double-click on an Analysis).

The panel edits a copy of the feature's inputs (:func:`analysis_feature.inputs_of`): fixed and
loaded faces picked in the 3D view, the total force, gravity, a material preset (or custom E,
ν, density and law), the grid cells and the output folder. **Run** shows the size estimate and
runs the ``parafab`` CLI in a QProcess (:class:`cli_runner.AnalysisRun`); the progress bar
follows its ``--progress`` lines and **Cancel run** kills it. Only a solved run writes the
inputs and results into the feature (and shows the coloured deformed mesh); a cancelled or
failed run only sets ``Status``. **OK** keeps what was done, **Cancel** undoes it (the panel
works inside one undo transaction).

GUI only: imported by the command and the view provider.
"""

import FreeCAD
import FreeCADGui
from PySide import QtCore, QtGui

from . import analysis_feature
from . import cli_runner
from . import icon_path

CUSTOM = "Custom"
#: The panel currently shown (for scripts and the GUI smoke test).
_active = None


def active_panel():
    """The open :class:`AnalysisTaskPanel`, or ``None``."""
    return _active


def open_panel(obj):
    """Show the task panel for feature ``obj``; returns True when shown."""
    global _active
    if FreeCADGui.Control.activeDialog():
        FreeCADGui.Control.closeDialog()
    _active = AnalysisTaskPanel(obj)
    FreeCADGui.Control.showDialog(_active)
    return True


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


def _spin(lo, hi, value, decimals=3, suffix=""):
    box = QtGui.QDoubleSpinBox()
    box.setRange(lo, hi)
    box.setDecimals(decimals)
    box.setValue(value)
    if suffix:
        box.setSuffix(suffix)
    _narrow(box)
    return box


def _narrow(widget, width=60):
    """Let ``widget`` shrink below its size hint: the combo view is often narrow."""
    widget.setMinimumWidth(width)
    return widget


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


class AnalysisTaskPanel(object):
    """The task dialog (``form`` + accept/reject) for one ``Analysis`` feature."""

    def __init__(self, obj):
        self.obj = obj
        self.doc = obj.Document
        self.run = None
        self.outcome = None
        self._own_transaction = False
        if not self.doc.HasPendingTransaction:
            self.doc.openTransaction("Edit analysis")
            self._own_transaction = True
        inputs = analysis_feature.inputs_of(obj)
        self.form = self._build(inputs)
        self.form.setWindowTitle("Analyze part")
        self.form.setWindowIcon(QtGui.QIcon(icon_path("ParaFab_Analysis.svg")))
        # Faces are picked on the part: show it while the panel is open.
        self._part_was_visible = obj.Part.ViewObject.Visibility if obj.Part else True
        if obj.Part and not obj.Dofs:
            obj.Part.ViewObject.Visibility = True
        self.update_estimate()

    # -- widgets -----------------------------------------------------------------------------

    def _build(self, inputs):
        form = QtGui.QWidget()
        layout = QtGui.QVBoxLayout(form)
        accepted = [o for o in (self.obj.Part, self.obj) if o is not None]

        loads = QtGui.QGroupBox("Supports and loads")
        lay = QtGui.QVBoxLayout(loads)
        part_label = self.obj.Part.Label if self.obj.Part else "?"
        hint = QtGui.QLabel("Part: %s. Pick faces in the 3D view, then add them." % part_label)
        hint.setWordWrap(True)
        lay.addWidget(hint)
        self.fixed = FaceList("Fixed faces", inputs["fixed"], accepted)
        self.loaded = FaceList("Loaded faces", inputs["loaded"], accepted)
        lay.addWidget(self.fixed)
        lay.addWidget(self.loaded)
        force_form = QtGui.QFormLayout()
        self.force = [_spin(-1e9, 1e9, v, 3, " N") for v in inputs["force"]]
        for axis, box in zip("xyz", self.force):
            force_form.addRow("Total force %s" % axis, box)
        lay.addLayout(force_form)
        self.gravity = QtGui.QCheckBox("Gravity (own weight, −z)")
        self.gravity.setChecked(inputs["gravity"])
        lay.addWidget(self.gravity)
        layout.addWidget(loads)

        mat = QtGui.QGroupBox("Material")
        grid = QtGui.QFormLayout(mat)
        grid.setRowWrapPolicy(QtGui.QFormLayout.WrapLongRows)
        self.preset = _narrow(QtGui.QComboBox())
        self.preset.addItems([name for name, _ in analysis_feature.MATERIALS] + [CUSTOM])
        self.E = _spin(1e-6, 1e9, inputs["E"], 3, " MPa")
        self.nu = _spin(-0.999, 0.499, inputs["nu"], 3)
        self.density = _spin(0.0, 1e6, inputs["density"], 1, " kg/m³")
        self.model = _narrow(QtGui.QComboBox())
        self.model.addItems(analysis_feature.MODELS)
        self.model.setCurrentIndex(max(0, self.model.findText(inputs["model"])))
        grid.addRow("Preset", self.preset)
        grid.addRow("Young's modulus E", self.E)
        grid.addRow("Poisson's ratio ν", self.nu)
        grid.addRow("Density", self.density)
        grid.addRow("Model", self.model)
        self.preset.setCurrentIndex(self.preset.findText(self._matching_preset(inputs)))
        self._preset_changed(self.preset.currentText())
        self.preset.currentTextChanged.connect(self._preset_changed)
        layout.addWidget(mat)

        out = QtGui.QGroupBox("Grid and output")
        form_out = QtGui.QFormLayout(out)
        form_out.setRowWrapPolicy(QtGui.QFormLayout.WrapLongRows)
        self.cells = QtGui.QSpinBox()
        self.cells.setRange(1, 1000)
        self.cells.setValue(inputs["cells"])
        self.cells.valueChanged.connect(self.update_estimate)
        self.cells.setToolTip("Grid cells along the part's longest side")
        form_out.addRow("Cells (longest side)", self.cells)
        self.element = _narrow(QtGui.QComboBox())
        self.element.addItems(analysis_feature.ELEMENTS)
        self.element.setCurrentIndex(max(0, self.element.findText(inputs["element"])))
        self.element.currentTextChanged.connect(self.update_estimate)
        self.element.setToolTip("hex27: triquadratic, more accurate per unknown (default); hex8: trilinear")
        form_out.addRow("Element", self.element)
        self.penalty = _narrow(QtGui.QComboBox())
        self.penalty.addItems(analysis_feature.PENALTIES)
        self.penalty.setCurrentIndex(max(0, self.penalty.findText(
            inputs.get("nitsche_penalty", analysis_feature.DEFAULT_PENALTY))))
        self.penalty.setToolTip("How the fixed faces are held on cut cells. auto (the default): local for the "
                                "linear model on hex27, fixed for hex8 and for rubber; local: from each cut cell's eigenvalue, stable "
                                "but on the thinnest slivers, no locking; fixed: penalty 100 E/h")
        form_out.addRow("Clamp penalty", self.penalty)
        folder_row = QtGui.QHBoxLayout()
        self.output_dir = _narrow(QtGui.QLineEdit(inputs["output_dir"]))
        self.output_dir.setPlaceholderText(analysis_feature.output_dir(self.obj, {"output_dir": ""}))
        browse = QtGui.QToolButton()
        browse.setText("…")
        browse.clicked.connect(self._browse)
        folder_row.addWidget(self.output_dir)
        folder_row.addWidget(browse)
        form_out.addRow("Output", folder_row)
        layout.addWidget(out)

        run = QtGui.QGroupBox("Run")
        lay = QtGui.QVBoxLayout(run)
        self.estimate_label = QtGui.QLabel()
        self.estimate_label.setWordWrap(True)
        lay.addWidget(self.estimate_label)
        buttons = QtGui.QHBoxLayout()
        self.run_button = QtGui.QPushButton("Run")
        self.cancel_button = QtGui.QPushButton("Cancel run")
        self.cancel_button.setEnabled(False)
        buttons.addWidget(self.run_button)
        buttons.addWidget(self.cancel_button)
        lay.addLayout(buttons)
        self.progress = QtGui.QProgressBar()
        self.progress.setRange(0, 100)
        self.progress.setValue(0)
        lay.addWidget(self.progress)
        self.status = QtGui.QLabel(self.obj.Status or "Not run yet")
        self.status.setWordWrap(True)
        self.status.setTextInteractionFlags(QtCore.Qt.TextSelectableByMouse)
        lay.addWidget(self.status)
        self.run_button.clicked.connect(self.start_run)
        self.cancel_button.clicked.connect(self.cancel_run)
        layout.addWidget(run)
        return form

    @staticmethod
    def _matching_preset(inputs):
        for name, m in analysis_feature.MATERIALS:
            if all(abs(m[k] - inputs[k]) <= 1e-9 * max(1.0, abs(m[k])) for k in ("E", "nu", "density")) \
                    and m["model"] == inputs["model"]:
                return name
        return CUSTOM

    def _preset_changed(self, name):
        custom = name == CUSTOM
        for widget in (self.E, self.nu, self.density, self.model):
            widget.setEnabled(custom)
        for preset, m in analysis_feature.MATERIALS:
            if preset == name:
                self.E.setValue(m["E"])
                self.nu.setValue(m["nu"])
                self.density.setValue(m["density"])
                self.model.setCurrentIndex(self.model.findText(m["model"]))

    def _browse(self):
        folder = QtGui.QFileDialog.getExistingDirectory(self.form, "Output folder", self.output_dir.text())
        if folder:
            self.output_dir.setText(folder)

    # -- inputs and estimate -----------------------------------------------------------------

    def inputs(self):
        """The inputs as edited in the panel (same keys as :func:`analysis_feature.inputs_of`)."""
        return {"fixed": self.fixed.faces(), "loaded": self.loaded.faces(),
                "force": tuple(box.value() for box in self.force), "gravity": self.gravity.isChecked(),
                "E": self.E.value(), "nu": self.nu.value(), "density": self.density.value(),
                "model": self.model.currentText(), "cells": self.cells.value(),
                "element": self.element.currentText(),
                "nitsche_penalty": self.penalty.currentText(),
                "output_dir": self.output_dir.text().strip()}

    def update_estimate(self, *args):
        if self.obj.Part is None:
            self.estimate_label.setText("No part linked")
            return
        unknowns, mb = analysis_feature.estimate(self.obj.Part, self.cells.value(), self.element.currentText())
        self.estimate_label.setText("Estimate: about %d unknowns, up to %.0f MB for the factorization" % (unknowns, mb))

    # -- running -----------------------------------------------------------------------------

    def start_run(self):
        """Start the CLI on the panel's inputs (no-op while a run is going)."""
        if self.run is not None and self.run.running():
            return False
        self.outcome = None
        self.update_estimate()
        self.progress.setValue(0)
        self.status.setText("Running… (%s)" % self.estimate_label.text())
        self.run_button.setEnabled(False)
        self.cancel_button.setEnabled(True)
        self.run = cli_runner.AnalysisRun(self.obj, self.inputs())
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
        self.progress.setFormat("%s %%p%%" % phase)

    def _done(self, outcome):
        self.outcome = outcome
        self.run_button.setEnabled(True)
        self.cancel_button.setEnabled(False)
        if outcome.state == cli_runner.SOLVED:
            self.progress.setValue(100)
            self.progress.setFormat("done")
            self.status.setText("%s\nEstimate: %s; %d DOFs; max displacement %s; max von Mises %s"
                                % (self.obj.Status, self.obj.Estimate, self.obj.Dofs,
                                   self.obj.MaxDisplacement.UserString, self.obj.MaxVonMises.UserString))
        elif outcome.state == cli_runner.CANCELLED:
            self.progress.setValue(0)
            self.progress.setFormat("cancelled")
            self.status.setText(self.obj.Status)
        else:
            self.progress.setValue(0)
            self.progress.setFormat("failed")
            self.status.setText(self.obj.Status)
        FreeCADGui.updateGui()

    # -- task dialog -------------------------------------------------------------------------

    def getStandardButtons(self):
        return int(QtGui.QDialogButtonBox.Ok | QtGui.QDialogButtonBox.Cancel)

    def _stop(self):
        if self.running():
            self.run.cancel()
            self.run.process.process.waitForFinished(5000)
            QtCore.QCoreApplication.processEvents()

    def _close(self):
        global _active
        try:
            part, solved = self.obj.Part, bool(self.obj.Dofs)
        except Exception:  # the feature was removed by undoing its creation
            part, solved = None, False
        if part is not None:
            # After a run the coloured result shows instead of the part.
            part.ViewObject.Visibility = False if solved else self._part_was_visible
        if _active is self:
            _active = None
        gui_doc = FreeCADGui.getDocument(self.doc.Name)
        if gui_doc is not None and gui_doc.getInEdit() is not None:
            gui_doc.resetEdit()
        FreeCADGui.Control.closeDialog()

    def accept(self):
        """OK: keep the results of the runs (and commit the undo transaction)."""
        self._stop()
        self.doc.commitTransaction()
        self._close()
        return True

    def reject(self):
        """Cancel: stop a run and undo everything done since the panel opened."""
        self._stop()
        self.doc.abortTransaction()
        self._close()
        return True
