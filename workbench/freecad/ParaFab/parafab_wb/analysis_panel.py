"""Task panel of the ``Analysis`` feature ("Analyze part", or double-click on an Analysis).

The panel edits a copy of the feature's inputs (:func:`analysis_job.inputs_of`): fixed and
loaded faces picked in the 3D view, the total force, gravity, a material preset (or custom E,
ν, density and law), the grid cells and the output folder. **Run** shows the size estimate and
runs the ``parafab`` CLI in a QProcess (:class:`cli_runner.AnalysisRun`); the progress bar
follows its ``--progress`` lines and **Cancel run** kills it. Only a solved run writes the
inputs and results into the feature (and shows the coloured deformed mesh); a cancelled or
failed run only sets ``Status``. **OK** keeps what was done, **Cancel** undoes it (the panel
works inside one undo transaction). Running, cancelling and closing are
:class:`task_panel.RunTaskPanel`'s.

GUI only: imported by the view provider (:mod:`parafab_wb.analysis_view`).
"""

import FreeCADGui
from PySide import QtGui

from . import analysis_job
from . import cli_runner
from . import task_panel
from .task_panel import FaceList, selected_faces  # noqa: F401  (their home before task_panel)

CUSTOM = "Custom"


def active_panel():
    """The open :class:`AnalysisTaskPanel`, or ``None``."""
    return AnalysisTaskPanel.active()


def open_panel(obj):
    """Show the task panel for feature ``obj``; returns True when shown."""
    AnalysisTaskPanel.show(obj)
    return True


def _spin(lo, hi, value, decimals=3, suffix=""):
    return task_panel.narrow(task_panel.spin(lo, hi, value, decimals, suffix))


_narrow = task_panel.narrow


class AnalysisTaskPanel(task_panel.RunTaskPanel):
    """The task dialog (``form`` + accept/reject) for one ``Analysis`` feature."""

    TITLE = "Analyze part"
    ICON = "ParaFab_Analysis.svg"
    TRANSACTION = "Edit analysis"
    #: "Analyze part" opens the transaction that creates the feature: the panel's OK commits
    #: it, its Cancel undoes the new feature too.
    ADOPTS_PENDING_TRANSACTION = True

    def __init__(self, obj):
        super(AnalysisTaskPanel, self).__init__(obj)
        inputs = analysis_job.inputs_of(obj)
        self.form = self.set_window(self._build(inputs))
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
        self.preset.addItems([name for name, _ in analysis_job.MATERIALS] + [CUSTOM])
        self.E = _spin(1e-6, 1e9, inputs["E"], 3, " MPa")
        self.nu = _spin(-0.999, 0.499, inputs["nu"], 3)
        self.density = _spin(0.0, 1e6, inputs["density"], 1, " kg/m³")
        self.model = _narrow(QtGui.QComboBox())
        self.model.addItems(analysis_job.MODELS)
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
        self.element.addItems(analysis_job.ELEMENTS)
        self.element.setCurrentIndex(max(0, self.element.findText(inputs["element"])))
        self.element.currentTextChanged.connect(self.update_estimate)
        self.element.setToolTip("hex27: triquadratic, more accurate per unknown (default); hex8: trilinear")
        form_out.addRow("Element", self.element)
        self.penalty = _narrow(QtGui.QComboBox())
        self.penalty.addItems(analysis_job.PENALTIES)
        self.penalty.setCurrentIndex(max(0, self.penalty.findText(
            inputs.get("nitsche_penalty", analysis_job.DEFAULT_PENALTY))))
        self.penalty.setToolTip("How the fixed faces are held on cut cells. auto (the default): local for the "
                                "linear model on hex27, fixed for hex8 and for rubber; local: from each cut cell's eigenvalue, stable "
                                "but on the thinnest slivers, no locking; fixed: penalty 100 E/h")
        form_out.addRow("Clamp penalty", self.penalty)
        folder_row = QtGui.QHBoxLayout()
        self.output_dir = _narrow(QtGui.QLineEdit(inputs["output_dir"]))
        self.output_dir.setPlaceholderText(analysis_job.output_dir(self.obj, {"output_dir": ""}))
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
        self.add_run_widgets(lay, self.obj.Status or "Not run yet")
        layout.addWidget(run)
        return form

    @staticmethod
    def _matching_preset(inputs):
        for name, m in analysis_job.MATERIALS:
            if all(abs(m[k] - inputs[k]) <= 1e-9 * max(1.0, abs(m[k])) for k in ("E", "nu", "density")) \
                    and m["model"] == inputs["model"]:
                return name
        return CUSTOM

    def _preset_changed(self, name):
        custom = name == CUSTOM
        for widget in (self.E, self.nu, self.density, self.model):
            widget.setEnabled(custom)
        for preset, m in analysis_job.MATERIALS:
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
        """The inputs as edited in the panel (same keys as :func:`analysis_job.inputs_of`)."""
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
        unknowns, mb = analysis_job.estimate(self.obj.Part, self.cells.value(), self.element.currentText())
        self.estimate_label.setText("Estimate: about %d unknowns, up to %.0f MB for the factorization" % (unknowns, mb))

    # -- running -----------------------------------------------------------------------------

    def running_text(self):
        self.update_estimate()
        return "Running… (%s)" % self.estimate_label.text()

    def make_run(self):
        return cli_runner.AnalysisRun(self.obj, self.inputs())

    def show_outcome(self, outcome):
        if outcome.state == cli_runner.SOLVED:
            self.status.setText("%s\nEstimate: %s; %d DOFs; max displacement %s; max von Mises %s"
                                % (self.obj.Status, self.obj.Estimate, self.obj.Dofs,
                                   self.obj.MaxDisplacement.UserString, self.obj.MaxVonMises.UserString))
        else:  # cancelled or failed: the feature's Status says which
            self.status.setText(self.obj.Status)

    def closing(self):
        try:
            part, solved = self.obj.Part, bool(self.obj.Dofs)
        except Exception:  # the feature was removed by undoing its creation
            part, solved = None, False
        if part is not None:
            # After a run the coloured result shows instead of the part.
            part.ViewObject.Visibility = False if solved else self._part_was_visible
        gui_doc = FreeCADGui.getDocument(self.doc.Name)
        if gui_doc is not None and gui_doc.getInEdit() is not None:
            gui_doc.resetEdit()
