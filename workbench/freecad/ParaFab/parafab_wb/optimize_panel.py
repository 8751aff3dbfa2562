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
**Cancel run** stops it (SIGTERM: the CLI writes its best iterate so far, not added) and leaves the
document as it was. A finished run adds
``<Label>_optimized`` beside the original and shows the objective before → after, the parameter
changes and the history chart (``history.png``). **OK** keeps the results, **Cancel** removes
them (one undo transaction). Running, cancelling and closing are :class:`task_panel.RunTaskPanel`'s.

GUI only: imported by the command.
"""

import FreeCAD
import FreeCADGui
from PySide import QtCore, QtGui

from . import optimize_feature
from . import optimize_runner
from . import task_panel
from .task_panel import FaceList, selected_faces, spin as _spin, wrapped as _wrapped

BOUND_TOOLTIP = ("Absolute bound of a checked parameter (double-click to edit; empty: none), e.g. a "
                 "minimum hole radius or wall position. Offsets and axis points are in the solid's own "
                 "frame (before its placement); radii and angles do not depend on it.")


def short_label(objective):
    """The objective's name as the combo shows it: its label without the explanation in
    brackets (that is shown below the combo and in its tooltip)."""
    return objective.label.split(" (")[0]


def active_panel():
    """The open :class:`OptimizeTaskPanel`, or ``None``."""
    return OptimizeTaskPanel.active()


def open_panel(obj, faces=()):
    """Show the panel for solid ``obj``; ``faces`` (``FaceN``) start checked. Returns the panel."""
    return OptimizeTaskPanel.show(obj, faces)


#: Largest coordinate [mm] and force [N] the spin boxes take (their width follows the widest value).
COORDINATE_RANGE = 1e6
FORCE_RANGE = 1e7


def _combo(min_chars=10):
    """A combo box as wide as its column: its list opens as wide as its longest entry."""
    box = QtGui.QComboBox()
    box.setSizeAdjustPolicy(QtGui.QComboBox.AdjustToMinimumContentsLengthWithIcon)
    box.setMinimumContentsLength(min_chars)
    box.setSizePolicy(QtGui.QSizePolicy.Expanding, QtGui.QSizePolicy.Fixed)
    return box


def _vector_rows(form, label, values, lo, hi, decimals, suffix=""):
    """Three spin boxes (prefixed x, y, z) of one vector, one per row of ``form`` under
    ``label`` (side by side they would not fit the task panel's width); returns them."""
    boxes = [_spin(lo, hi, v, decimals, suffix, "%s " % axis) for axis, v in zip("xyz", values)]
    for i, box in enumerate(boxes):
        form.addRow(label if i == 0 else "", box)
    return boxes


def _form():
    form = QtGui.QFormLayout()
    form.setRowWrapPolicy(QtGui.QFormLayout.WrapLongRows)
    form.setFieldGrowthPolicy(QtGui.QFormLayout.AllNonFixedFieldsGrow)
    return form


class Section(QtGui.QWidget):
    """A titled part of the panel that folds: its header (a flat arrow button) shows or hides
    its body; folded, a one-line summary says what it holds."""

    def __init__(self, title, expanded=True, parent=None):
        super(Section, self).__init__(parent)
        self.title = title
        outer = QtGui.QVBoxLayout(self)
        outer.setContentsMargins(0, 0, 0, 0)
        outer.setSpacing(2)
        self.header = QtGui.QToolButton()
        self.header.setText(title)
        self.header.setCheckable(True)
        self.header.setToolButtonStyle(QtCore.Qt.ToolButtonTextBesideIcon)
        self.header.setSizePolicy(QtGui.QSizePolicy.Expanding, QtGui.QSizePolicy.Fixed)
        self.header.setAutoRaise(True)
        font = self.header.font()
        font.setBold(True)
        self.header.setFont(font)
        self.header.setToolTip("Show or hide the %s settings" % title.lower())
        outer.addWidget(self.header)
        self.summary = _wrapped("")
        self.summary.setContentsMargins(18, 0, 0, 0)
        self.summary.setStyleSheet("color: #555555")
        outer.addWidget(self.summary)
        self.body = QtGui.QFrame()
        self.body.setFrameShape(QtGui.QFrame.StyledPanel)
        self.layout = QtGui.QVBoxLayout(self.body)
        self.layout.setContentsMargins(6, 6, 6, 6)
        outer.addWidget(self.body)
        self.header.toggled.connect(self.set_expanded)
        self.header.setChecked(expanded)
        self.set_expanded(expanded)

    def set_expanded(self, expanded):
        """Unfold (True) or fold the section."""
        if self.header.isChecked() != bool(expanded):
            self.header.setChecked(bool(expanded))  # comes back here through toggled
            return
        self.header.setArrowType(QtCore.Qt.DownArrow if expanded else QtCore.Qt.RightArrow)
        self.body.setVisible(bool(expanded))
        self.summary.setVisible(not expanded and bool(self.summary.text()))

    def expanded(self):
        return self.header.isChecked()

    def set_summary(self, text):
        """What the folded section holds (shown below its header while it is folded)."""
        self.summary.setText(text)
        self.summary.setVisible(not self.expanded() and bool(text))

    def add_form(self):
        form = _form()
        self.layout.addLayout(form)
        return form


def _bound_row(form, label, hi, decimals, suffix, tooltip):
    """A spin box from 0 ("no bound") to ``hi`` under ``label``, its own row of ``form``."""
    box = _spin(0.0, hi, 0.0, decimals, suffix)
    box.setSpecialValueText("no bound")
    box.setToolTip(tooltip)
    form.addRow(QtGui.QLabel(label))
    form.addRow(box)
    return box


def _group(title):
    """A titled box inside a section (draft, pattern, mirror, ...); returns it and its layout."""
    group = QtGui.QGroupBox(title)
    lay = QtGui.QVBoxLayout(group)
    lay.setContentsMargins(4, 4, 4, 4)
    return group, lay


class OptimizeTaskPanel(task_panel.RunTaskPanel):
    """The task dialog (``form`` + accept/reject) for optimizing one solid."""

    TITLE = "Optimize shape"
    ICON = "ParaFab_OptimizeShape.svg"
    TRANSACTION = "Optimize shape"
    PROGRESS_FORMAT = "%s  %%p%%"

    def __init__(self, obj, faces=()):
        super(OptimizeTaskPanel, self).__init__(obj)
        self.results = []
        try:
            self.model = optimize_feature.face_model(obj)
            model_error = ""
        except optimize_feature.OptimizeError as exc:
            self.model = {"faces": [], "groups": [], "relations": 0}
            model_error = str(exc)
        vobj = getattr(obj, "ViewObject", None)
        self._transparency = vobj.Transparency if vobj is not None else 0
        self.form = self.set_window(self._build())
        if not self.check_faces(list(faces)):
            self.auto.setChecked(True)  # nothing picked: a default that runs as it is
        if model_error:
            self.status.setText(model_error)

    # -- widgets -----------------------------------------------------------------------------

    def _build(self):
        form = QtGui.QWidget()
        layout = QtGui.QVBoxLayout(form)
        layout.setContentsMargins(0, 0, 0, 0)
        defaults = optimize_feature.default_options()
        self.sections = {}
        for key, title, expanded in (("faces", "Part and faces", True), ("objective", "Objective", True),
                                     ("constraints", "Constraints", False), ("run", "Run", True)):
            self.sections[key] = Section(title, expanded)
            layout.addWidget(self.sections[key])
        layout.addStretch(1)
        self._build_faces(self.sections["faces"], defaults)
        self._build_objective(self.sections["objective"], defaults)
        self._build_constraints(self.sections["constraints"], defaults)
        self._build_run(self.sections["run"], defaults)
        self.objective.currentIndexChanged.connect(self._objective_changed)
        self._objective_changed()
        self._mass_changed()
        self.update_summaries()
        return form

    def _build_faces(self, section, defaults):
        """Design parameters (the face tree), supports, loads and the force."""
        lay = section.layout
        lay.addWidget(_wrapped("%s: %d faces, %d relations (tangent or coaxial faces), %d groups (a group "
                               "moves together)." % (self.obj.Label, len(self.model["faces"]),
                                                     self.model["relations"], len(self.model["groups"]))))
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
        self.tree.header().resizeSection(0, 150)
        self.tree.itemChanged.connect(lambda *args: self.update_summaries())
        lay.addWidget(self.tree)
        pick = QtGui.QPushButton("Check selected faces")
        pick.setToolTip("Check the offset/radius of the faces selected in the 3D view")
        pick.clicked.connect(lambda: self.check_faces(selected_faces([self.obj])))
        lay.addWidget(pick)
        self.auto.toggled.connect(self.tree.setDisabled)
        self.auto.toggled.connect(lambda *args: self.update_summaries())

        loads, loads_lay = _group("Supports and loads")
        loads_lay.addWidget(_wrapped("Fixed faces, unless a checked parameter is on one (then it moves with its "
                                     "face). Objectives with a material need both."))
        self.supports = FaceList("Supports (fixed faces)", [], [self.obj])
        self.loads = FaceList("Loaded faces", [], [self.obj])
        loads_lay.addWidget(self.supports)
        loads_lay.addWidget(self.loads)
        force = _form()
        self.force = _vector_rows(force, "Total force", (0.0, 0.0, 0.0), -FORCE_RANGE, FORCE_RANGE, 3, " N")
        loads_lay.addLayout(force)
        lay.addWidget(loads)

    def _build_objective(self, section, defaults):
        """The objective and its inputs (axis, density, failure, matched face, clamp)."""
        lay = section.layout
        lay.addWidget(QtGui.QLabel("Minimize"))
        self.objective = _combo(12)
        for o in optimize_feature.OBJECTIVES:
            self.objective.addItem(short_label(o), o.type)
            self.objective.setItemData(self.objective.count() - 1, o.tooltip, QtCore.Qt.ToolTipRole)
        lay.addWidget(self.objective)
        self.objective_text = _wrapped("")
        self.objective_text.setStyleSheet("color: #555555")
        lay.addWidget(self.objective_text)
        grid = section.add_form()
        self.axis_point = _vector_rows(grid, "Axis point", defaults["axis_point"], -COORDINATE_RANGE,
                                       COORDINATE_RANGE, 3, " mm")
        self.axis_dir = _vector_rows(grid, "Axis direction", defaults["axis_direction"], -1, 1, 4)
        self.density = _spin(0.0, 1e6, defaults["density"], 1, " kg/m³")
        self.density.setToolTip("Density of the mass objective and of the mass bounds (Constraints)")
        grid.addRow("Density", self.density)
        self.yield_stress = _spin(0.0, 1e6, defaults["yield_stress"], 1, " MPa")
        self.yield_stress.setToolTip("σ_y of the failure objective")
        grid.addRow("Yield stress", self.yield_stress)
        self.exponent = _spin(0.0, 1e3, defaults["exponent"], 2)
        self.exponent.setToolTip("α of the failure objective: larger is nearer the maximum stress")
        grid.addRow("Exponent α", self.exponent)
        target_tip = ("Target shape: the face that must land on its own CAD surface (plane, cylinder, sphere or "
                      "torus) under the load; not a support")
        self.target_face = _combo(8)
        self.target_face.addItem("(choose a face)", None)
        for f in self.model["faces"]:
            self.target_face.addItem("%s (%s)" % (f["name"], f["type"]), f["name"])
        self.target_face.setToolTip(target_tip)
        grid.addRow(QtGui.QLabel("Matched face"))
        grid.addRow(self.target_face)  # whole rows: face names are long
        self.target_pick = QtGui.QPushButton("Use selected face")
        self.target_pick.setToolTip("Match the face selected in the 3D view")
        self.target_pick.clicked.connect(self.use_selected_target)
        grid.addRow(self.target_pick)
        self.penalty = _combo(6)
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

    def _build_constraints(self, section, defaults):
        """Volume and mass bounds (the job's "constraints"), draft, pattern and mirror faces."""
        lay = section.layout
        bounds, bounds_lay = _group("Volume and mass")
        grid = _form()
        bounds_lay.addLayout(grid)
        self.volume_ratio = _bound_row(grid, "Max volume ratio", 10.0, 3, "", "Volume at most this times the "
                                       "original's (0: no bound); the job's {\"type\": \"volume\", \"max_ratio\"}")
        self.min_volume_ratio = _bound_row(grid, "Min volume ratio", 10.0, 3, "", "Volume at least this times the "
                                           "original's (0: no bound); the job's {\"type\": \"volume\", \"min_ratio\"}")
        mass_tip = ("%s mass of the optimized solid in kg: density (Objective, kg/m³) × 1e-9 × volume (mm³); "
                    "0: no bound. Sent as the job's {\"type\": \"mass\"} constraint with the density in kg/mm³")
        self.max_mass = _bound_row(grid, "Max mass", 1e9, 6, " kg", mass_tip % "Largest")
        self.min_mass = _bound_row(grid, "Min mass", 1e9, 6, " kg", mass_tip % "Smallest")
        self.start_mass = _wrapped("", "The original's mass: what the mass bounds are compared with at the start")
        grid.addRow("Start mass", self.start_mass)
        self.mass_message = _wrapped("")
        self.mass_message.setStyleSheet("color: #b00000")
        grid.addRow(self.mass_message)
        for box in (self.density, self.max_mass, self.min_mass):
            box.valueChanged.connect(self._mass_changed)
        for box in (self.volume_ratio, self.min_volume_ratio, self.max_mass, self.min_mass):
            box.valueChanged.connect(lambda *args: self.update_summaries())
        lay.addWidget(bounds)

        draft, draft_lay = _group("Draft")
        draft_lay.addWidget(_wrapped("Walls stay parallel to the pull direction (undercut-free for casting or "
                                     "moulding along it)."))
        self.draft_faces = FaceList("Draft faces (planes, cylinders, cones)", [], [self.obj])
        self.draft_faces.setToolTip("Planar faces whose normal stays orthogonal to the pull direction, cylinders "
                                    "and cones whose axis stays parallel to it (undercut-free for casting or "
                                    "moulding along it)")
        draft_lay.addWidget(self.draft_faces)
        pull = _form()
        self.draft_dir = _vector_rows(pull, "Pull direction", defaults["draft_direction"], -1, 1, 4)
        draft_lay.addLayout(pull)
        lay.addWidget(draft)

        self.pattern_faces, self.pattern_point, self.pattern_dir = self._faces_point_direction_group(
            lay, "Pattern", "Faces turned about an axis change alike.", "Pattern faces (one of each copy)",
            "Equal faces spaced evenly about the axis (bolt holes, spokes): the design of one is copied to all; "
            "pick them in any order", ("Axis point", defaults["pattern_axis_point"]),
            ("Axis direction", defaults["pattern_axis_direction"]))
        self.mirror_faces, self.mirror_point, self.mirror_normal = self._faces_point_direction_group(
            lay, "Mirror", "Faces and their images in a plane change alike.", "Mirror faces (both of each pair)",
            "Pairs of faces that are images of each other in the plane: each pair keeps its symmetry; pick them "
            "in any order", ("Plane point", defaults["mirror_plane_point"]),
            ("Plane normal", defaults["mirror_plane_normal"]))
        for faces in (self.draft_faces, self.pattern_faces, self.mirror_faces):
            faces.list.model().rowsInserted.connect(lambda *args: self.update_summaries())
            faces.list.model().rowsRemoved.connect(lambda *args: self.update_summaries())

    def _build_run(self, section, defaults):
        """Iterations, output folder, Run / Cancel run, progress, results and charts."""
        lay = section.layout
        out = section.add_form()
        self.iterations = QtGui.QSpinBox()
        self.iterations.setRange(1, 1000)
        self.iterations.setValue(defaults["max_iterations"])
        out.addRow("Max iterations", self.iterations)
        lay.addWidget(QtGui.QLabel("Output folder"))
        self.output_dir = QtGui.QLineEdit()
        self.output_dir.setPlaceholderText(optimize_feature.default_output_dir(self.obj))
        self.output_dir.setToolTip("Folder of job.json, optimized.step, history.json and the charts (empty: %s)"
                                   % optimize_feature.default_output_dir(self.obj))
        lay.addWidget(self.output_dir)
        self.add_run_widgets(lay)
        self.changes = QtGui.QListWidget()
        self.changes.setMaximumHeight(90)
        self.changes.setToolTip("Design parameters: initial -> final")
        lay.addWidget(self.changes)
        self.charts = QtGui.QTabWidget()
        self.chart = QtGui.QLabel("history chart after a run")
        self.before_after = QtGui.QLabel("before/after chart after a run")
        for label, title in ((self.chart, "History"), (self.before_after, "Before/after")):
            label.setAlignment(QtCore.Qt.AlignCenter)
            label.setWordWrap(True)
            label.setMinimumHeight(150)
            self.charts.addTab(label, title)
        lay.addWidget(self.charts)
        self.open_chart = QtGui.QPushButton("Open chart")
        self.open_chart.setToolTip("Show the chart of the current tab full size")
        self.open_chart.setEnabled(False)
        self.open_chart.clicked.connect(self.show_chart)
        lay.addWidget(self.open_chart)

    def update_summaries(self):
        """The one-line summaries the folded sections show."""
        if self.auto.isChecked():
            design = "all parameters (auto)"
        else:
            design = "%d parameters checked" % len(self.checked_parameters())
        self.sections["faces"].set_summary("%s; %d supports, %d loaded faces" % (
            design, len(self.supports.faces()), len(self.loads.faces())))
        self.sections["objective"].set_summary(self.objective.currentText())
        bounds = []
        for text, value in (("V ≤ %g V0", self.volume_ratio.value()), ("V ≥ %g V0", self.min_volume_ratio.value()),
                            ("m ≤ %g kg", self.max_mass.value()), ("m ≥ %g kg", self.min_mass.value())):
            if value > 0:
                bounds.append(text % value)
        for name, faces in (("draft", self.draft_faces), ("pattern", self.pattern_faces),
                            ("mirror", self.mirror_faces)):
            if faces.faces():
                bounds.append("%s: %d faces" % (name, len(faces.faces())))
        self.sections["constraints"].set_summary(", ".join(bounds) or "none")
        self.sections["run"].set_summary("%d iterations; %s" % (self.iterations.value(), self.status.text()))

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
        objective = optimize_feature.objective_by_type(self.objective.currentData())
        uses = objective.uses
        short = short_label(objective)
        explanation = objective.label[len(short):].strip(" ()")
        self.objective_text.setText(explanation[:1].upper() + explanation[1:] if explanation else objective.tooltip)
        self.objective_text.setToolTip(objective.tooltip)
        if hasattr(self, "sections"):
            self.update_summaries()
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
        for name in selected_faces([self.obj]):
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

    def _faces_point_direction_group(self, layout, title, text, faces_label, tooltip, point, direction):
        """A group of picked faces with a point [mm] and a direction (x/y/z rows), added to
        ``layout``; returns the face list and the two rows of spin boxes."""
        group, lay = _group(title)
        lay.addWidget(_wrapped(text))
        faces = FaceList(faces_label, [], [self.obj])
        faces.setToolTip(tooltip)
        lay.addWidget(faces)
        rows = _form()
        point_boxes = _vector_rows(rows, point[0], point[1], -COORDINATE_RANGE, COORDINATE_RANGE, 3, " mm")
        direction_boxes = _vector_rows(rows, direction[0], direction[1], -1, 1, 4)
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
                "min_volume_ratio": self.min_volume_ratio.value() or None,
                "max_mass": self.max_mass.value() or None, "min_mass": self.min_mass.value() or None}

    # -- running -----------------------------------------------------------------------------

    def run_problem(self):
        return self.mass_problem()

    def make_run(self):
        return optimize_runner.OptimizeRun(self.obj, self.options(), self.output_dir.text().strip() or None)

    def show_outcome(self, outcome):
        if outcome.state == optimize_runner.SOLVED:
            new = self.run.result_object
            self.results.append(new)
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
            self.status.setText("%s: %s (document unchanged)" % (outcome.state, outcome.message))
        self.update_summaries()

    def _show(self, label, path, history_file):
        pixmap = QtGui.QPixmap(path) if path else QtGui.QPixmap()
        if pixmap.isNull():
            label.setPixmap(QtGui.QPixmap())
            label.setText("no chart (history in %s)" % history_file)
        else:
            width = max(100, self.charts.contentsRect().width() - 16)  # inside the tab frame
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

    def undo(self):
        """Cancel: remove the solids the panel added (also when undo is off), restore the
        original's transparency."""
        for new in self.results:
            try:
                if self.doc.getObject(new.Name) is not None:
                    self.doc.removeObject(new.Name)
            except Exception:
                pass
        if self.obj.ViewObject is not None:
            self.obj.ViewObject.Transparency = self._transparency
