"""Task panel of "Optimize shape" (the command ``ParaFab_OptimizeShape`` on a selected solid).

Shows the solid's faces grouped by the face model's relations (a group moves together: a moved
plane drags its fillet along, a countersink its hole) with each face's parameters (offset, normal,
radius, axis, ...), checkable as design parameters with optional Min / Max bounds (double-click
a cell), or "all parameters" (``"auto"``); the
objective (from :data:`optimize_feature.OBJECTIVES`, with its axis or density, or for "Target
shape" the matched face: a combo of the solid's faces or the face selected in the 3D view);
supports and loads (their faces stay fixed unless a checked parameter is on one: then it moves with its face); iterations, a volume bound and mass bounds (max / min in kg, the
start mass density × ``Shape.Volume`` shown beside them, crossing bounds or a bound without a
density named in the panel). **Run** runs ``parafab optimize``
in a QProcess (:class:`optimize_runner.OptimizeRun`): the progress bar follows its iterates,
**Cancel run** kills it and leaves the document as it was. A finished run adds
``<Label>_optimized`` beside the original and shows the objective before → after, the parameter
changes and the history chart (``history.png``). **OK** keeps the results, **Cancel** removes
them (one undo transaction).

GUI only: imported by the command.
"""

import FreeCAD
import FreeCADGui
from PySide import QtCore, QtGui

from . import analysis_panel
from . import icon_path
from . import optimize_feature
from . import optimize_runner

_active = None

BOUND_TOOLTIP = ("Absolute bound of a checked parameter (double-click to edit; empty: none), e.g. a "
                 "minimum hole radius or wall position. Offsets and axis points are in the solid's own "
                 "frame (before its placement); radii and angles do not depend on it.")


def active_panel():
    """The open :class:`OptimizeTaskPanel`, or ``None``."""
    return _active


def open_panel(obj, faces=()):
    """Show the panel for solid ``obj``; ``faces`` (``FaceN``) start checked. Returns the panel."""
    global _active
    if FreeCADGui.Control.activeDialog():
        FreeCADGui.Control.closeDialog()
    _active = OptimizeTaskPanel(obj, faces)
    FreeCADGui.Control.showDialog(_active)
    return _active


def _spin(lo, hi, value, decimals=3, suffix=""):
    return analysis_panel._spin(lo, hi, value, decimals, suffix)


def _vector_row(form, label, boxes):
    """Adds the spin boxes of one vector (x, y, z) side by side as a row of ``form``."""
    row = QtGui.QHBoxLayout()
    for b in boxes:
        row.addWidget(b)
    form.addRow(label, row)


class OptimizeTaskPanel(object):
    """The task dialog (``form`` + accept/reject) for optimizing one solid."""

    def __init__(self, obj, faces=()):
        self.obj = obj
        self.doc = obj.Document
        self.run = None
        self.outcome = None
        self.results = []
        self._own_transaction = False
        if not self.doc.HasPendingTransaction:
            self.doc.openTransaction("Optimize shape")
            self._own_transaction = True
        try:
            self.model = optimize_feature.face_model(obj)
            model_error = ""
        except optimize_feature.OptimizeError as exc:
            self.model = {"faces": [], "groups": [], "relations": 0}
            model_error = str(exc)
        vobj = getattr(obj, "ViewObject", None)
        self._transparency = vobj.Transparency if vobj is not None else 0
        self.form = self._build()
        self.form.setWindowTitle("Optimize shape")
        self.form.setWindowIcon(QtGui.QIcon(icon_path("ParaFab_OptimizeShape.svg")))
        self.check_faces(list(faces))
        if model_error:
            self.status.setText(model_error)

    # -- widgets -----------------------------------------------------------------------------

    def _build(self):
        form = QtGui.QWidget()
        layout = QtGui.QVBoxLayout(form)
        defaults = optimize_feature.default_options()

        params = QtGui.QGroupBox("Design parameters")
        lay = QtGui.QVBoxLayout(params)
        hint = QtGui.QLabel("%s: %d faces, %d relations (tangent or coaxial faces), %d groups (a group "
                            "moves together)." % (
                                self.obj.Label, len(self.model["faces"]), self.model["relations"],
                                len(self.model["groups"])))
        hint.setWordWrap(True)
        lay.addWidget(hint)
        self.auto = QtGui.QCheckBox("All parameters (auto)")
        self.auto.setToolTip("Every parameter of every analytic face that is not fixed")
        lay.addWidget(self.auto)
        self.tree = QtGui.QTreeWidget()
        self.tree.setColumnCount(3)
        self.tree.setHeaderLabels(["Parameter", "Min", "Max"])
        self.tree.headerItem().setToolTip(1, BOUND_TOOLTIP)
        self.tree.headerItem().setToolTip(2, BOUND_TOOLTIP)
        # Only the bound columns are edited (double click), never the parameter's name.
        self.tree.setEditTriggers(QtGui.QAbstractItemView.NoEditTriggers)
        self.tree.itemDoubleClicked.connect(self._edit_bound)
        self.tree.setMinimumHeight(140)
        self._param_items = {}
        faces = {f["name"]: f for f in self.model["faces"]}
        grouped = set()
        for k, group in enumerate(self.model["groups"]):
            top = QtGui.QTreeWidgetItem(["Tangency group %d: %s" % (k + 1, ", ".join(group))])
            self.tree.addTopLevelItem(top)
            for name in group:
                grouped.add(name)
                self._add_face(top, faces[name])
        rest = [f for f in self.model["faces"] if f["name"] not in grouped]
        if rest:
            top = QtGui.QTreeWidgetItem(["Faces without tangency (%d)" % len(rest)])
            self.tree.addTopLevelItem(top)
            for f in rest:
                self._add_face(top, f)
        self.tree.expandToDepth(0)
        lay.addWidget(self.tree)
        pick = QtGui.QPushButton("Check selected faces")
        pick.setToolTip("Check the offset/radius of the faces selected in the 3D view")
        pick.clicked.connect(lambda: self.check_faces(analysis_panel.selected_faces([self.obj])))
        lay.addWidget(pick)
        self.auto.toggled.connect(self.tree.setDisabled)
        layout.addWidget(params)

        objective = QtGui.QGroupBox("Objective")
        grid = QtGui.QFormLayout(objective)
        grid.setRowWrapPolicy(QtGui.QFormLayout.WrapLongRows)
        self.objective = analysis_panel._narrow(QtGui.QComboBox())
        for o in optimize_feature.OBJECTIVES:
            self.objective.addItem(o.label, o.type)
            self.objective.setItemData(self.objective.count() - 1, o.tooltip, QtCore.Qt.ToolTipRole)
        grid.addRow("Minimize", self.objective)
        self.axis_point = [_spin(-1e9, 1e9, v, 3, " mm") for v in defaults["axis_point"]]
        self.axis_dir = [_spin(-1, 1, v, 4) for v in defaults["axis_direction"]]
        _vector_row(grid, "Axis point", self.axis_point)
        _vector_row(grid, "Axis direction", self.axis_dir)
        self.density = _spin(0.0, 1e6, defaults["density"], 1, " kg/m³")
        grid.addRow("Density", self.density)
        self.yield_stress = _spin(0.0, 1e6, defaults["yield_stress"], 1, " MPa")
        self.yield_stress.setToolTip("σ_y of the failure objective")
        grid.addRow("Yield stress", self.yield_stress)
        self.exponent = _spin(0.0, 1e3, defaults["exponent"], 2)
        self.exponent.setToolTip("α of the failure objective: larger is nearer the maximum stress")
        grid.addRow("Exponent α", self.exponent)
        target_tip = ("Target shape: the face that must land on its own CAD surface (plane, cylinder, sphere or "
                      "torus) under the load; not a support")
        self.target_face = analysis_panel._narrow(QtGui.QComboBox())
        self.target_face.addItem("(choose a face)", None)
        for f in self.model["faces"]:
            self.target_face.addItem("%s (%s)" % (f["name"], f["type"]), f["name"])
        self.target_face.setToolTip(target_tip)
        self.target_pick = analysis_panel._narrow(QtGui.QPushButton("Use selected"))
        self.target_pick.setToolTip("Match the face selected in the 3D view")
        self.target_pick.clicked.connect(self.use_selected_target)
        row = QtGui.QHBoxLayout()
        row.addWidget(self.target_face)
        row.addWidget(self.target_pick)
        grid.addRow("Matched face", row)
        self.iterations = QtGui.QSpinBox()
        self.iterations.setRange(1, 1000)
        self.iterations.setValue(defaults["max_iterations"])
        grid.addRow("Max iterations", self.iterations)
        self.volume_ratio = _spin(0.0, 10.0, 0.0, 3)
        self.volume_ratio.setSpecialValueText("no bound")
        self.volume_ratio.setToolTip("Volume at most this times the original's (0: no bound)")
        grid.addRow("Max volume ratio", self.volume_ratio)
        mass_tip = ("%s mass of the optimized solid in kg: density (above, kg/m³) × 1e-9 × volume (mm³); "
                    "0: no bound. Sent as the job's {\"type\": \"mass\"} constraint with the density in kg/mm³")
        self.max_mass = _spin(0.0, 1e9, 0.0, 6, " kg")
        self.max_mass.setSpecialValueText("no bound")
        self.max_mass.setToolTip(mass_tip % "Largest")
        grid.addRow("Max mass", self.max_mass)
        self.min_mass = _spin(0.0, 1e9, 0.0, 6, " kg")
        self.min_mass.setSpecialValueText("no bound")
        self.min_mass.setToolTip(mass_tip % "Smallest")
        grid.addRow("Min mass", self.min_mass)
        self.start_mass = QtGui.QLabel()
        self.start_mass.setWordWrap(True)
        self.start_mass.setToolTip("The original's mass: what the mass bounds are compared with at the start")
        grid.addRow("Start mass", self.start_mass)
        self.mass_message = QtGui.QLabel()
        self.mass_message.setWordWrap(True)
        self.mass_message.setStyleSheet("color: #b00000")
        grid.addRow("", self.mass_message)
        for box in (self.density, self.max_mass, self.min_mass):
            box.valueChanged.connect(self._mass_changed)
        self.penalty = analysis_panel._narrow(QtGui.QComboBox())
        self.penalty.addItems(["fixed", "local"])
        self.penalty.setCurrentIndex(max(0, self.penalty.findText(defaults.get("nitsche_penalty", "fixed"))))
        self.penalty.setToolTip("How the supports are held on cut cells (objectives with a material). fixed: "
                                "penalty 100 E/h; local: from each cut cell's eigenvalue, stable but on the thinnest slivers, no "
                                "locking (the entries near a support are then differenced, slower)")
        grid.addRow("Clamp penalty", self.penalty)
        self.merge = QtGui.QCheckBox("Smooth joins")
        self.merge.setChecked(bool(defaults.get("merge_penalty", False)))
        self.merge.setToolTip("Compliance only (thesis Eq. 6.24): pieces of a cut cell closer than 5 % of a cell are "
                              "tied, so the objective does not jump where a shape change joins or splits them "
                              "(costs an OCCT Boolean per such cell and evaluation)")
        grid.addRow("", self.merge)
        self.objective.currentIndexChanged.connect(self._objective_changed)
        layout.addWidget(objective)

        loads = QtGui.QGroupBox("Supports and loads (fixed faces unless a checked parameter is on one)")
        lay = QtGui.QVBoxLayout(loads)
        self.supports = analysis_panel.FaceList("Supports (fixed faces)", [], [self.obj])
        self.loads = analysis_panel.FaceList("Loaded faces", [], [self.obj])
        lay.addWidget(self.supports)
        lay.addWidget(self.loads)
        force = QtGui.QFormLayout()
        self.force = [_spin(-1e9, 1e9, 0.0, 3, " N") for _ in range(3)]
        for axis, box in zip("xyz", self.force):
            force.addRow("Total force %s" % axis, box)
        lay.addLayout(force)
        layout.addWidget(loads)

        draft = QtGui.QGroupBox("Draft (walls stay parallel to the pull direction)")
        lay = QtGui.QVBoxLayout(draft)
        self.draft_faces = analysis_panel.FaceList("Draft faces (planes, cylinders, cones)", [], [self.obj])
        self.draft_faces.setToolTip("Planar faces whose normal stays orthogonal to the pull direction, cylinders "
                                    "and cones whose axis stays parallel to it (undercut-free for casting or "
                                    "moulding along it)")
        lay.addWidget(self.draft_faces)
        self.draft_dir = [_spin(-1, 1, v, 4) for v in defaults["draft_direction"]]
        pull = QtGui.QFormLayout()
        _vector_row(pull, "Pull direction", self.draft_dir)
        lay.addLayout(pull)
        layout.addWidget(draft)

        self.pattern_faces, self.pattern_point, self.pattern_dir = self._faces_point_direction_group(
            layout, "Pattern (faces turned about an axis change alike)", "Pattern faces (one of each copy)",
            "Equal faces spaced evenly about the axis (bolt holes, spokes): the design of one is copied to all; "
            "pick them in any order", ("Axis point", defaults["pattern_axis_point"]),
            ("Axis direction", defaults["pattern_axis_direction"]))
        self.mirror_faces, self.mirror_point, self.mirror_normal = self._faces_point_direction_group(
            layout, "Mirror (faces and their images in a plane change alike)", "Mirror faces (both of each pair)",
            "Pairs of faces that are images of each other in the plane: each pair keeps its symmetry; pick them "
            "in any order", ("Plane point", defaults["mirror_plane_point"]),
            ("Plane normal", defaults["mirror_plane_normal"]))

        out = QtGui.QFormLayout()
        self.output_dir = analysis_panel._narrow(QtGui.QLineEdit())
        self.output_dir.setPlaceholderText(optimize_feature.default_output_dir(self.obj))
        out.addRow("Output", self.output_dir)
        layout.addLayout(out)

        run = QtGui.QGroupBox("Run")
        lay = QtGui.QVBoxLayout(run)
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
        self.status = QtGui.QLabel("Not run yet")
        self.status.setWordWrap(True)
        self.status.setTextInteractionFlags(QtCore.Qt.TextSelectableByMouse)
        lay.addWidget(self.status)
        self.changes = QtGui.QListWidget()
        self.changes.setMaximumHeight(90)
        self.changes.setToolTip("Design parameters: initial -> final")
        lay.addWidget(self.changes)
        self.charts = QtGui.QTabWidget()
        self.chart = QtGui.QLabel("history chart after a run")
        self.before_after = QtGui.QLabel("before/after chart after a run")
        for label, title in ((self.chart, "History"), (self.before_after, "Before/after")):
            label.setAlignment(QtCore.Qt.AlignCenter)
            label.setMinimumHeight(150)
            self.charts.addTab(label, title)
        lay.addWidget(self.charts)
        self.open_chart = QtGui.QPushButton("Open chart")
        self.open_chart.setToolTip("Show the chart of the current tab full size")
        self.open_chart.setEnabled(False)
        self.open_chart.clicked.connect(self.show_chart)
        lay.addWidget(self.open_chart)
        self.run_button.clicked.connect(self.start_run)
        self.cancel_button.clicked.connect(self.cancel_run)
        layout.addWidget(run)
        self._objective_changed()
        self._mass_changed()
        return form

    def _add_face(self, parent, face):
        item = QtGui.QTreeWidgetItem(parent, ["%s (%s)" % (face["name"], face["type"])])
        for name in face["parameters"]:
            child = QtGui.QTreeWidgetItem(item, [name, "", ""])
            child.setFlags(child.flags() | QtCore.Qt.ItemIsUserCheckable | QtCore.Qt.ItemIsEditable)
            child.setToolTip(1, BOUND_TOOLTIP)
            child.setToolTip(2, BOUND_TOOLTIP)
            child.setCheckState(0, QtCore.Qt.Unchecked)
            self._param_items[(face["name"], name)] = child
        if not face["parameters"]:
            item.setText(0, "%s (%s: fixed, no shape parameters)" % (face["name"], face["type"]))

    def check_faces(self, names):
        """Check the default parameter (offset, radius) of faces ``names``; returns those checked."""
        checked = []
        types = {f["name"]: f["type"] for f in self.model["faces"]}
        for name in names:
            param = optimize_feature.default_parameter(types.get(name, ""))
            item = self._param_items.get((name, param))
            if item is not None:
                item.setCheckState(0, QtCore.Qt.Checked)
                item.parent().setExpanded(True)
                checked.append((name, param))
        return checked

    def _objective_changed(self, *args):
        uses = optimize_feature.objective_by_type(self.objective.currentData()).uses
        for b in self.axis_point + self.axis_dir:
            b.setEnabled("axis" in uses)
        self.density.setEnabled("density" in uses or "material" in uses or self._mass_bounded())
        self.yield_stress.setEnabled("failure" in uses)
        self.exponent.setEnabled("failure" in uses)
        self.target_face.setEnabled("target" in uses)
        self.target_pick.setEnabled("target" in uses)
        self.merge.setEnabled(self.objective.currentData() == "compliance")

    def set_target_face(self, name):
        """Choose face ``name`` (``FaceN``) as the matched face of "Target shape"; returns whether
        it is a face of the solid."""
        index = self.target_face.findData(name)
        if index < 0:
            return False
        self.target_face.setCurrentIndex(index)
        return True

    def use_selected_target(self):
        """The first face selected in the 3D view on the solid becomes the matched face; returns
        its name or ``None``."""
        for name in analysis_panel.selected_faces([self.obj]):
            if self.set_target_face(name):
                return name
        FreeCAD.Console.PrintWarning("ParaFab: select the matched face of %s in the 3D view first\n" % self.obj.Label)
        return None

    def _mass_bounded(self):
        return self.max_mass.value() > 0 or self.min_mass.value() > 0

    def mass_problem(self):
        """Why the mass bounds cannot be sent (min above max, no density), or ``""``."""
        try:
            optimize_feature.mass_constraint(self._mass_options())
        except optimize_feature.OptimizeError as exc:
            return str(exc)
        return ""

    def _mass_options(self):
        return {"density": self.density.value(),
                "max_mass": self.max_mass.value() or None, "min_mass": self.min_mass.value() or None}

    def _mass_changed(self, *args):
        """Start mass (density × FreeCAD's ``Shape.Volume``) and the bounds' validation message."""
        try:
            volume = optimize_feature.solid_shape(self.obj).Volume
        except optimize_feature.OptimizeError:
            volume = None
        density = self.density.value()
        if volume is None:
            self.start_mass.setText("no solid")
        elif density > 0:
            self.start_mass.setText("%.6g kg (%g kg/m³ × %.6g mm³)" % (
                optimize_feature.start_mass(self.obj.Shape, density), density, volume))
        else:
            self.start_mass.setText("no density (volume %.6g mm³)" % volume)
        problem = self.mass_problem()
        self.mass_message.setText(problem)
        self.mass_message.setVisible(bool(problem))
        if self._mass_bounded():
            self.density.setEnabled(True)
        else:
            self._objective_changed()

    # -- options -----------------------------------------------------------------------------

    def _edit_bound(self, item, column):
        if column in (1, 2) and item in self._param_items.values():
            self.tree.editItem(item, column)

    def set_bounds(self, face, name, lower=None, upper=None):
        """Fill the Min / Max cells of parameter ``name`` of ``face`` (None: empty, no bound)."""
        item = self._param_items[(face, name)]
        for column, value in ((1, lower), (2, upper)):
            item.setText(column, "" if value is None else repr(float(value)))

    def checked_parameters(self):
        """Checked parameters: (face, name), or (face, name, min, max) when a bound cell is filled
        (an empty cell: None; the engine checks the numbers)."""
        out = []
        for key, item in self._param_items.items():
            if item.checkState(0) != QtCore.Qt.Checked:
                continue
            bounds = [item.text(c).strip() or None for c in (1, 2)]
            out.append(key if bounds == [None, None] else key + tuple(bounds))
        return out

    def _faces_point_direction_group(self, layout, title, faces_label, tooltip, point, direction):
        """A group of picked faces with a point [mm] and a direction (x/y/z rows), added to
        ``layout``; returns the face list and the two rows of spin boxes."""
        group = QtGui.QGroupBox(title)
        lay = QtGui.QVBoxLayout(group)
        faces = analysis_panel.FaceList(faces_label, [], [self.obj])
        faces.setToolTip(tooltip)
        lay.addWidget(faces)
        point_boxes = [_spin(-1e9, 1e9, v, 3, " mm") for v in point[1]]
        direction_boxes = [_spin(-1, 1, v, 4) for v in direction[1]]
        rows = QtGui.QFormLayout()
        _vector_row(rows, point[0], point_boxes)
        _vector_row(rows, direction[0], direction_boxes)
        lay.addLayout(rows)
        layout.addWidget(group)
        return faces, point_boxes, direction_boxes

    def options(self):
        """The job options of :func:`optimize_feature.build_job` as edited in the panel."""
        ratio = self.volume_ratio.value()
        return {"objective": self.objective.currentData(),
                "axis_point": tuple(b.value() for b in self.axis_point),
                "axis_direction": tuple(b.value() for b in self.axis_dir),
                "density": self.density.value(),
                "yield_stress": self.yield_stress.value(), "exponent": self.exponent.value(),
                "target_face": self.target_face.currentData(),
                "parameters": "auto" if self.auto.isChecked() else self.checked_parameters(),
                "supports": self.supports.faces(), "loads": self.loads.faces(),
                "draft_faces": self.draft_faces.faces(),
                "draft_direction": tuple(b.value() for b in self.draft_dir),
                "pattern_faces": self.pattern_faces.faces(),
                "pattern_axis_point": tuple(b.value() for b in self.pattern_point),
                "pattern_axis_direction": tuple(b.value() for b in self.pattern_dir),
                "mirror_faces": self.mirror_faces.faces(),
                "mirror_plane_point": tuple(b.value() for b in self.mirror_point),
                "mirror_plane_normal": tuple(b.value() for b in self.mirror_normal),
                "force": tuple(b.value() for b in self.force),
                "max_iterations": self.iterations.value(),
                "nitsche_penalty": self.penalty.currentText(),
                "merge_penalty": self.merge.isChecked() and self.merge.isEnabled(),
                "max_volume_ratio": ratio if ratio > 0 else None,
                "max_mass": self.max_mass.value() or None, "min_mass": self.min_mass.value() or None}

    # -- running -----------------------------------------------------------------------------

    def start_run(self):
        if self.running():
            return False
        problem = self.mass_problem()
        if problem:
            self.status.setText("Not run: %s" % problem)
            return False
        self.outcome = None
        self.progress.setValue(0)
        self.progress.setFormat("starting %p%")
        self.status.setText("Running…")
        self.run_button.setEnabled(False)
        self.cancel_button.setEnabled(True)
        self.run = optimize_runner.OptimizeRun(self.obj, self.options(), self.output_dir.text().strip() or None)
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
        self.progress.setFormat("%s  %%p%%" % phase)

    def _done(self, outcome):
        self.outcome = outcome
        self.run_button.setEnabled(True)
        self.cancel_button.setEnabled(False)
        if outcome.state == optimize_runner.SOLVED:
            new = self.run.result_object
            self.results.append(new)
            self.progress.setValue(100)
            self.progress.setFormat("done")
            extra = "".join("; " + text for text in (optimize_feature.target_summary(new),
                                                     optimize_feature.mass_summary(new)) if text)
            self.status.setText("%s added: %s; volume × %.4f%s; written to %s" % (
                new.Label, optimize_feature.summary(self.run.history), new.VolumeRatio, extra, self.run.out_dir))
            self.changes.clear()
            self.changes.addItems(list(new.ParameterChanges))
            self._show(self.chart, new.HistoryChart, new.HistoryFile)
            self._show(self.before_after, new.BeforeAfterChart, new.HistoryFile)
            self.open_chart.setEnabled(True)
        else:
            self.progress.setValue(0)
            self.progress.setFormat("cancelled" if outcome.state == optimize_runner.CANCELLED else "failed")
            self.status.setText("%s: %s (document unchanged)" % (outcome.state, outcome.message))
        FreeCADGui.updateGui()

    def _show(self, label, path, history_file):
        pixmap = QtGui.QPixmap(path) if path else QtGui.QPixmap()
        if pixmap.isNull():
            label.setPixmap(QtGui.QPixmap())
            label.setText("no chart (history in %s)" % history_file)
        else:
            width = max(200, self.charts.width() - 10)
            label.setPixmap(pixmap.scaled(width, 260, QtCore.Qt.KeepAspectRatio, QtCore.Qt.SmoothTransformation))
        label.setToolTip(path or "")

    def show_chart(self):
        """A window with the chart of the current tab at full size; returns it."""
        label = self.charts.currentWidget()
        pixmap = QtGui.QPixmap(label.toolTip())
        if pixmap.isNull():
            return None
        dialog = QtGui.QDialog(FreeCADGui.getMainWindow())
        dialog.setWindowTitle("%s: %s" % (self.obj.Label, self.charts.tabText(self.charts.currentIndex())))
        lay = QtGui.QVBoxLayout(dialog)
        view = QtGui.QLabel()
        view.setPixmap(pixmap)
        lay.addWidget(view)
        dialog.setAttribute(QtCore.Qt.WA_DeleteOnClose)
        dialog.show()
        return dialog

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
        if _active is self:
            _active = None
        FreeCADGui.Control.closeDialog()

    def accept(self):
        """OK: keep the optimized solids."""
        self._stop()
        if self._own_transaction:
            self.doc.commitTransaction()
        self._close()
        return True

    def reject(self):
        """Cancel: stop a run and remove what the panel added."""
        self._stop()
        if self._own_transaction:
            self.doc.abortTransaction()
        for new in self.results:  # also when undo is off
            try:
                if self.doc.getObject(new.Name) is not None:
                    self.doc.removeObject(new.Name)
            except Exception:
                pass
        if self.obj.ViewObject is not None:
            self.obj.ViewObject.Transparency = self._transparency
        self._close()
        return True
