"""GUI smoke test of the ParaFab workbench (FreeCAD macro).

Run by ``tests/gui/gui_smoke.sh`` as ``freecad gui_smoke_macro.py`` under
Xvfb, with the workbench installed in FreeCAD's user Mod directory.  Steps:

1. activate the ParaFab workbench, check its command, toolbar and menu;
2. create a sketch holding a B-spline, select its edge;
3. run ``ParaFab_Strip`` through ``FreeCADGui.runCommand``, recompute;
4. fit the view and save a screenshot; check the strip's colour is visible;
5. save, close and reopen the document; recompute;
6. "Analyze part" on the L-bracket (``$PARAFAB_SAMPLES_DIR/parts/l_bracket.step``): select the
   back face, run the command, check the task panel opens with it fixed; pick the loaded face
   with "Add selected faces", set the force and a 10-cell grid, press Run and wait for the
   ``parafab`` CLI (QProcess) to finish; check the progress bar, the results and the coloured
   deformed mesh; run again and press "Cancel run" at the first progress line (results must
   stay as they were); OK; screenshot of the coloured part; reopen the panel by editing the
   feature and close it with Cancel; save and reopen.

7. "Optimize shape" on the wheel (``parts/wheel.step``): select a spoke side face and the hub
   hole, run the command, check the panel lists the faces with those two parameters checked; set
   3 iterations and Run (the ``parafab optimize`` CLI in a QProcess); check the new
   ``Wheel_optimized`` solid, the original untouched, the status, the parameter changes and the
   history chart shown; run again and cancel at the first iterate (nothing added); OK.

Checked on the way: the workbench's tooltip and menu name its capabilities; the analysis
and the optimized solid show their colour scale with its unit (``von Mises [MPa]``, ``Face
moved [mm]``, read back from the scene graph and seen in the screenshots); nothing in the
Optimize panel is cut off at the task panel's default width (:func:`cut_off_widgets`, as it
opens and after a run, every section unfolded).

Results go to ``$PARAFAB_ARTIFACT_DIR`` (``status.json``, ``strip.png``, ``analysis.png``,
``analysis_panel.png``, ``optimize_panel_open.png``, ``optimize_panel.png``, ``optimize.png``).
FreeCAD is then left with ``os._exit`` (0 = pass, 1 = fail), so no dialog
("save changes?") can block the run.
"""

import json
import os
import tempfile
import traceback

import FreeCAD
import FreeCADGui
import Part

ARTIFACT_DIR = os.environ.get("PARAFAB_ARTIFACT_DIR") or tempfile.mkdtemp()
STATUS_FILE = os.path.join(ARTIFACT_DIR, "status.json")
SCREENSHOT = os.path.join(ARTIFACT_DIR, "strip.png")
DOCUMENT = os.path.join(ARTIFACT_DIR, "gui_smoke.FCStd")
ANALYSIS_SCREENSHOT = os.path.join(ARTIFACT_DIR, "analysis.png")
PANEL_SCREENSHOT = os.path.join(ARTIFACT_DIR, "analysis_panel.png")
ANALYSIS_DOCUMENT = os.path.join(ARTIFACT_DIR, "gui_smoke_analysis.FCStd")
ANALYSIS_OUT = os.path.join(ARTIFACT_DIR, "analysis_out")
OPTIMIZE_SCREENSHOT = os.path.join(ARTIFACT_DIR, "optimize_panel.png")
OPTIMIZE_OPEN_SCREENSHOT = os.path.join(ARTIFACT_DIR, "optimize_panel_open.png")
OPTIMIZE_VIEW = os.path.join(ARTIFACT_DIR, "optimize.png")
OPTIMIZE_OUT = os.path.join(ARTIFACT_DIR, "optimize_out")
SAMPLES_DIR = os.environ.get("PARAFAB_SAMPLES_DIR", "")
#: Seconds to wait for the CLI run of the bracket.
RUN_TIMEOUT = 120

#: Minimum number of strip-coloured pixels expected in the screenshot.
MIN_STRIP_PIXELS = 2000


class Checks(object):
    """Named checks recorded for the status file."""

    def __init__(self):
        self.results = {}

    def __call__(self, name, condition, detail=""):
        self.results[name] = bool(condition)
        if not condition:
            raise AssertionError("%s failed %s" % (name, detail))


def strip_pixels(path):
    """Count orange (strip colour) pixels in the PNG at ``path``."""
    from PySide2 import QtGui
    image = QtGui.QImage(path)
    count = 0
    for y in range(0, image.height(), 2):
        for x in range(0, image.width(), 2):
            c = QtGui.QColor(image.pixel(x, y))
            if c.red() > 120 and c.red() - c.blue() > 80 and c.green() > 40:
                count += 1
    return count * 4


def color_pixels(path):
    """Counts of saturated pixels per hue band (blue, cyan, green, yellow, red) in the PNG."""
    from PySide2 import QtGui
    image = QtGui.QImage(path)
    bands = {"blue": 0, "cyan": 0, "green": 0, "yellow": 0, "red": 0}
    for y in range(0, image.height(), 2):
        for x in range(0, image.width(), 2):
            c = QtGui.QColor(image.pixel(x, y))
            if c.saturation() < 120 or c.value() < 60:
                continue
            h = c.hue()
            band = ("red" if h < 20 or h >= 300 else "yellow" if h < 75 else "green" if h < 150
                    else "cyan" if h < 200 else "blue")
            bands[band] += 4
    return bands


def wait_for(condition, seconds):
    """Process GUI events until ``condition()`` holds or ``seconds`` pass; returns it."""
    import time
    from PySide2 import QtCore
    end = time.time() + seconds
    while not condition() and time.time() < end:
        QtCore.QCoreApplication.processEvents(QtCore.QEventLoop.AllEvents, 50)
        time.sleep(0.01)
    return condition()


def face_at(shape, point):
    """``FaceN`` of the face of ``shape`` through ``point``."""
    vertex = Part.Vertex(FreeCAD.Vector(*point))
    for i, face in enumerate(shape.Faces):
        if face.distToShape(vertex)[0] < 1e-6:
            return "Face%d" % (i + 1)
    raise AssertionError("no face through %s" % (point,))


def scroll_area(widget):
    """The QScrollArea (FreeCAD's task view) that holds ``widget``, or ``None``."""
    from PySide2 import QtWidgets
    area = widget.parent()
    while area is not None and not isinstance(area, QtWidgets.QScrollArea):
        area = area.parent()
    return area


def _describe(widget):
    text = ""
    for attr in ("text", "currentText", "title", "placeholderText"):
        if hasattr(widget, attr):
            try:
                text = getattr(widget, attr)()
            except TypeError:
                continue
            if text:
                break
    if hasattr(widget, "cleanText") and not text:
        text = widget.text()
    name = widget.objectName()
    return "%s%s '%s'" % (type(widget).__name__, "(%s)" % name if name else "", text[:40])


def cut_off_widgets(form):
    """Every visible button, label, line edit, spin box, combo box and group box of the task
    panel ``form`` that is cut off: narrower than its size hint (labels and buttons; a
    word-wrapped label: its minimum size hint), than its minimum size hint (line edits, spin
    boxes, combo boxes, group boxes), a combo box whose current text does not fit its field, or
    one that reaches past the task panel's visible width. Returns "widget: why" lines."""
    from PySide2 import QtCore, QtWidgets
    area = scroll_area(form)
    viewport = area.viewport() if area is not None else form
    visible = viewport.width()
    problems = []
    kinds = (QtWidgets.QAbstractButton, QtWidgets.QLabel, QtWidgets.QLineEdit, QtWidgets.QAbstractSpinBox,
             QtWidgets.QComboBox, QtWidgets.QGroupBox)
    for w in form.findChildren(QtWidgets.QWidget):
        if not isinstance(w, kinds) or not w.isVisible():
            continue
        if isinstance(w, QtWidgets.QLineEdit) and isinstance(w.parent(), (QtWidgets.QAbstractSpinBox,
                                                                          QtWidgets.QComboBox)):
            continue  # the editor inside a spin box or combo box: checked as that box
        if isinstance(w, QtWidgets.QLabel) and w.wordWrap():
            need, what = w.minimumSizeHint().width(), "minimumSizeHint"
        elif isinstance(w, (QtWidgets.QLabel, QtWidgets.QAbstractButton)):
            need, what = w.sizeHint().width(), "sizeHint"
        else:
            need, what = w.minimumSizeHint().width(), "minimumSizeHint"
        if w.width() < need:
            problems.append("%s: %d px wide, %s %d px" % (_describe(w), w.width(), what, need))
        if isinstance(w, QtWidgets.QComboBox) and w.currentText():
            opt = QtWidgets.QStyleOptionComboBox()
            opt.initFrom(w)
            opt.editable = w.isEditable()
            opt.currentText = w.currentText()
            field = w.style().subControlRect(QtWidgets.QStyle.CC_ComboBox, opt,
                                             QtWidgets.QStyle.SC_ComboBoxEditField, w)
            text = w.fontMetrics().horizontalAdvance(w.currentText())
            if field.width() < text:
                problems.append("%s: text %d px in a %d px field" % (_describe(w), text, field.width()))
        left = w.mapTo(viewport, QtCore.QPoint(0, 0)).x() if area is not None else w.mapTo(form, QtCore.QPoint(0, 0)).x()
        if left < 0 or left + w.width() > visible:
            problems.append("%s: spans x %d..%d, the panel shows 0..%d" % (_describe(w), left, left + w.width(), visible))
    return problems


def legend_pixels(path):
    """Hue bands at the bottom and the top of the colour scale (parafab_wb.legend's bar at the
    left of the view) in the screenshot at ``path``: (bottom, top)."""
    from PySide2 import QtGui
    from parafab_wb import legend
    image = QtGui.QImage(path)

    def band(y):
        x = int(round((0.5 * (legend.BAR_X[0] + legend.BAR_X[1]) + 1) / 2 * image.width()))
        py = int(round((1 - y) / 2 * image.height()))
        c = QtGui.QColor(image.pixel(x, py))
        if c.saturation() < 120 or c.value() < 60:
            return "none"
        h = c.hue()
        return ("red" if h < 20 or h >= 300 else "yellow" if h < 75 else "green" if h < 150
                else "cyan" if h < 200 else "blue")
    return band(legend.BAR_Y[0] + 0.02), band(legend.BAR_Y[1] - 0.02)


def legacy_copy(source, target, old, new):
    """Copy FCStd ``source`` to ``target`` with ``old`` replaced by ``new`` in its
    GuiDocument.xml; returns how many times it was replaced."""
    import zipfile
    count = 0
    with zipfile.ZipFile(source) as zin, zipfile.ZipFile(target, "w", zipfile.ZIP_DEFLATED) as zout:
        for item in zin.infolist():
            data = zin.read(item.filename)
            if item.filename == "GuiDocument.xml":
                text = data.decode("utf-8")
                count = text.count(old)
                data = text.replace(old, new).encode("utf-8")
            zout.writestr(item, data)
    return count


def run_analysis(check):
    """Step 6: the "Analyze part" task panel on the L-bracket."""
    from parafab_wb import analysis_panel, cli_runner
    check("analyze_command_registered", "ParaFab_AnalyzePart" in FreeCADGui.listCommands())
    doc = FreeCAD.newDocument("GuiAnalysis")
    part = doc.addObject("Part::Feature", "Bracket")
    part.Shape = Part.read(os.path.join(SAMPLES_DIR, "parts", "l_bracket.step"))
    doc.recompute()
    fixed = face_at(part.Shape, (0, 20, 30))   # back of the upright
    loaded = face_at(part.Shape, (60, 20, 4))  # free end of the base
    FreeCADGui.Selection.clearSelection()
    FreeCADGui.Selection.addSelection(doc.Name, part.Name, fixed)
    FreeCADGui.updateGui()
    FreeCADGui.runCommand("ParaFab_AnalyzePart")
    FreeCADGui.updateGui()
    panel = analysis_panel.active_panel()
    check("panel_open", panel is not None and FreeCADGui.Control.activeDialog())
    analysis = panel.obj
    check("panel_fixed_face", panel.fixed.faces() == [fixed], panel.fixed.faces())
    cli = cli_runner.find_cli()
    check("cli_found", cli is not None and os.access(cli, os.X_OK), cli)

    FreeCADGui.Selection.clearSelection()
    FreeCADGui.Selection.addSelection(doc.Name, part.Name, loaded)
    panel.loaded.add_button.click()
    check("panel_loaded_face", panel.loaded.faces() == [loaded], panel.loaded.faces())
    panel.force[2].setValue(-500.0)
    panel.preset.setCurrentIndex(panel.preset.findText("Steel"))
    panel.cells.setValue(10)
    check("panel_penalty_default", panel.penalty.currentText() == "auto", panel.penalty.currentText())
    panel.penalty.setCurrentIndex(panel.penalty.findText("local"))
    panel.output_dir.setText(ANALYSIS_OUT)
    check("panel_estimate", "unknowns" in panel.estimate_label.text(), panel.estimate_label.text())

    phases = []
    panel.run_button.click()
    panel.run.progress.connect(lambda phase, fraction: phases.append(phase))
    check("run_started", not panel.run_button.isEnabled() and panel.cancel_button.isEnabled())
    check("run_finished", wait_for(lambda: panel.outcome is not None, RUN_TIMEOUT))
    check("run_solved", panel.outcome.state == cli_runner.SOLVED, panel.outcome.message)
    check("run_progress_lines", phases[:2] == ["read", "cut"] and "write" in phases, phases)
    check("progress_bar_full", panel.progress.value() == 100, panel.progress.value())
    check("results_stored", analysis.Dofs > 0 and analysis.MaxDisplacement.Value > 0, analysis.Status)
    check("status_solved", analysis.Status.startswith("solved"), analysis.Status)
    mesh = analysis.ResultMesh
    check("result_mesh", mesh is not None and mesh.Mesh.CountPoints > 0)
    check("result_mesh_colors", len(mesh.VertexColors) == mesh.Mesh.CountPoints
          and mesh.ViewObject.Coloring)
    check("result_mesh_child", mesh in analysis.ViewObject.Proxy.claimChildren())
    from parafab_wb import legend
    texts = legend.texts(mesh.ViewObject)
    check("analysis_legend", texts[-1:] == ["von Mises [MPa]"] and len(texts) == 6
          and texts[0] == legend.format_value(min(mesh.VonMises))
          and texts[-2] == legend.format_value(max(mesh.VonMises)), texts)
    check("inputs_stored", list(analysis.LoadedFaces) == [loaded] and analysis.Cells == 10
          and abs(analysis.Force.z + 500) < 1e-9 and analysis.NitschePenalty == "local")
    solved = (analysis.Dofs, analysis.MaxDisplacement.Value, mesh.Mesh.CountPoints, analysis.Cells)
    FreeCADGui.updateGui()
    FreeCADGui.getMainWindow().grab().save(PANEL_SCREENSHOT)

    # Cancel a second run at its first progress line: nothing but Status changes.
    panel.cells.setValue(12)
    panel.run_button.click()
    panel.run.progress.connect(lambda phase, fraction: panel.cancel_button.click())
    check("cancel_finished", wait_for(lambda: panel.outcome is not None, RUN_TIMEOUT))
    check("cancel_outcome", panel.outcome.state == cli_runner.CANCELLED, panel.outcome)
    check("cancel_status", analysis.Status.startswith("cancelled"), analysis.Status)
    check("cancel_kept_results", (analysis.Dofs, analysis.MaxDisplacement.Value, mesh.Mesh.CountPoints,
                                  analysis.Cells) == solved)
    check("cancel_progress_bar", panel.progress.format() == "cancelled", panel.progress.format())

    panel.accept()
    FreeCADGui.updateGui()
    check("panel_closed", not FreeCADGui.Control.activeDialog())
    check("undo_analysis", "Analyze part" in doc.UndoNames, doc.UndoNames)
    check("part_hidden", not part.ViewObject.Visibility)

    view = FreeCADGui.getDocument(doc.Name).activeView()
    view.viewIsometric()
    view.fitAll()
    FreeCADGui.updateGui()
    view.saveImage(ANALYSIS_SCREENSHOT, 1280, 1024, "White")
    bands = color_pixels(ANALYSIS_SCREENSHOT)
    check("analysis_colors_visible", bands["blue"] >= 2000 and sum(v >= 500 for v in bands.values()) >= 3,
          bands)
    scale_bands = legend_pixels(ANALYSIS_SCREENSHOT)
    check("analysis_legend_visible", scale_bands == ("blue", "red"), scale_bands)

    # Double-click path: the view provider opens the panel; Cancel keeps the results.
    FreeCADGui.getDocument(doc.Name).setEdit(analysis.Name, 0)
    FreeCADGui.updateGui()
    panel = analysis_panel.active_panel()
    check("panel_reopened", panel is not None and panel.obj == analysis
          and panel.loaded.faces() == [loaded] and panel.cells.value() == 10)
    panel.reject()
    FreeCADGui.updateGui()
    check("panel_reject_closed", not FreeCADGui.Control.activeDialog())
    check("reject_kept_results", analysis.Dofs == solved[0] and analysis.ResultMesh is not None)

    # "Analyze part" again, then Cancel in the panel: the new feature and its mesh are undone.
    names = sorted(o.Name for o in doc.Objects)
    FreeCADGui.Selection.clearSelection()
    FreeCADGui.Selection.addSelection(doc.Name, part.Name, fixed)
    FreeCADGui.runCommand("ParaFab_AnalyzePart")
    FreeCADGui.updateGui()
    panel = analysis_panel.active_panel()
    check("second_panel_open", panel is not None and panel.obj != analysis
          and len(doc.Objects) == len(names) + 2)
    panel.reject()
    FreeCADGui.updateGui()
    check("reject_removed_new_analysis", sorted(o.Name for o in doc.Objects) == names,
          sorted(o.Name for o in doc.Objects))

    name = analysis.Name
    doc.saveAs(ANALYSIS_DOCUMENT)
    FreeCAD.closeDocument(doc.Name)
    doc = FreeCAD.openDocument(ANALYSIS_DOCUMENT)
    analysis = doc.getObject(name)
    check("reopened_analysis_view_provider",
          type(analysis.ViewObject.Proxy).__name__ == "ViewProviderAnalysis")
    check("reopened_result_mesh", analysis.ResultMesh is not None
          and analysis.ResultMesh.Mesh.CountPoints == solved[2] and analysis.ResultMesh.ViewObject.Coloring)
    check("reopened_legend", legend.texts(analysis.ResultMesh.ViewObject) == texts,
          legend.texts(analysis.ResultMesh.ViewObject))
    scale = analysis.DeformationScale
    FreeCAD.closeDocument(doc.Name)

    # A document saved before the view provider moved from analysis_feature to analysis_view
    # names it by its old path: it still gets its view provider, result mesh and legend.
    legacy = os.path.join(ARTIFACT_DIR, "gui_smoke_analysis_legacy.FCStd")
    moved = legacy_copy(ANALYSIS_DOCUMENT, legacy, 'module="parafab_wb.analysis_view"',
                        'module="parafab_wb.analysis_feature"')
    check("legacy_document_written", moved == 1, moved)
    # Restored from the file, not made anew by the feature's fallback for documents without one
    # (that would call __init__; FreeCAD restores a proxy without it).
    from parafab_wb import analysis_view
    made = []
    original_init = analysis_view.ViewProviderAnalysis.__init__
    analysis_view.ViewProviderAnalysis.__init__ = lambda self, vobj: (made.append(vobj), original_init(self, vobj))
    try:
        doc = FreeCAD.openDocument(legacy)
    finally:
        analysis_view.ViewProviderAnalysis.__init__ = original_init
    analysis = doc.getObject(name)
    proxy = analysis.ViewObject.Proxy
    check("legacy_view_provider", type(proxy) is analysis_view.ViewProviderAnalysis and not made
          and analysis.ResultMesh in proxy.claimChildren(), (type(proxy), len(made)))
    check("legacy_legend", legend.texts(analysis.ResultMesh.ViewObject) == texts,
          legend.texts(analysis.ResultMesh.ViewObject))
    FreeCAD.closeDocument(doc.Name)
    return {"analysis_dofs": solved[0], "analysis_max_displacement_mm": solved[1],
            "analysis_deformation_scale": scale,
            "analysis_color_pixels": bands, "analysis_legend": texts, "cli": cli, "analysis_screenshot": ANALYSIS_SCREENSHOT}


def settle(seconds=0.5):
    """Process GUI events for ``seconds``: the task view lays its panel out again once its
    vertical scroll bar appears (its horizontal one is always off: what is wider is cut off)."""
    wait_for(lambda: False, seconds)
    FreeCADGui.updateGui()


def panel_cut_off(panel):
    """:func:`cut_off_widgets` of the Optimize panel as it is and with each of its sections
    unfolded (all at once: the widest case); section states are restored."""
    settle()
    problems = cut_off_widgets(panel.form)
    sections = getattr(panel, "sections", {})
    states = dict((k, s.expanded()) for k, s in sections.items())
    for s in sections.values():
        s.set_expanded(True)
    settle()
    problems += [p for p in cut_off_widgets(panel.form) if p not in problems]
    for k, s in sections.items():
        s.set_expanded(states[k])
    settle()
    return problems


def run_optimize(check):
    """Step 7: the "Optimize shape" task panel on the wheel."""
    from parafab_wb import optimize_panel, optimize_runner
    check("optimize_command_registered", "ParaFab_OptimizeShape" in FreeCADGui.listCommands())
    doc = FreeCAD.newDocument("GuiOptimize")
    part = doc.addObject("Part::Feature", "Wheel")
    part.Shape = Part.read(os.path.join(SAMPLES_DIR, "parts", "wheel.step"))
    doc.recompute()
    spoke = next("Face%d" % (i + 1) for i, f in enumerate(part.Shape.Faces)
                 if isinstance(f.Surface, Part.Plane) and abs(f.Surface.Axis.z) < 0.5)
    hole = next("Face%d" % (i + 1) for i, f in enumerate(part.Shape.Faces)
                if isinstance(f.Surface, Part.Cylinder) and abs(f.Surface.Radius - 5) < 1e-6)
    volume = part.Shape.Volume
    FreeCADGui.Selection.clearSelection()
    FreeCADGui.Selection.addSelection(doc.Name, part.Name, spoke)
    FreeCADGui.Selection.addSelection(doc.Name, part.Name, hole)
    FreeCADGui.updateGui()
    FreeCADGui.runCommand("ParaFab_OptimizeShape")
    FreeCADGui.updateGui()
    panel = optimize_panel.active_panel()
    check("optimize_panel_open", panel is not None and FreeCADGui.Control.activeDialog())
    check("optimize_panel_faces", panel.tree.topLevelItemCount() >= 1
          and len(panel.model["faces"]) == len(part.Shape.Faces))
    check("optimize_panel_checked", sorted(panel.checked_parameters()) == sorted(
        [(spoke, "offset"), (hole, "radius")]), panel.checked_parameters())
    check("optimize_objective_default", panel.objective.currentData() == "center_of_mass")
    FreeCADGui.updateGui()
    FreeCADGui.getMainWindow().grab().save(OPTIMIZE_OPEN_SCREENSHOT)
    cut_off = panel_cut_off(panel)
    check("optimize_panel_nothing_cut_off", not cut_off, "\n" + "\n".join(cut_off))
    # Min / Max cells of a checked parameter reach the job as absolute bounds.
    panel.set_bounds(hole, "radius", 4.0, 5.5)
    bounded = dict((p[0], p) for p in panel.checked_parameters())[hole]
    check("optimize_panel_bound_cells", bounded == (hole, "radius", "4.0", "5.5"), bounded)
    from parafab_wb import optimize_feature
    job = optimize_feature.build_job(part.Shape, panel.options())
    entry = [e for e in job["parameters"] if e["parameter"] == "radius"]
    check("optimize_panel_bounds_in_job", len(entry) == 1 and entry[0].get("min") == 4.0 and entry[0].get("max") == 5.5,
          job["parameters"])
    opts = panel.options()
    check("optimize_panel_symmetry_groups", opts["mirror_faces"] == [] and opts["pattern_faces"] == []
          and tuple(opts["mirror_plane_normal"]) == (1.0, 0.0, 0.0)
          and tuple(opts["pattern_axis_direction"]) == (0.0, 0.0, 1.0), str(opts))
    panel.iterations.setValue(3)
    panel.output_dir.setText(OPTIMIZE_OUT)
    names = sorted(o.Name for o in doc.Objects)
    panel.run_button.click()
    check("optimize_run_finished", wait_for(lambda: panel.outcome is not None, RUN_TIMEOUT))
    check("optimize_run_solved", panel.outcome.state == optimize_runner.SOLVED, panel.outcome.message)
    new = panel.run.result_object
    check("optimize_result_added", new is not None and len(doc.Objects) == len(names) + 1
          and new.Label == "Wheel_optimized" and new.Shape.isValid())
    check("optimize_original_untouched", abs(part.Shape.Volume - volume) < 1e-9 * volume)
    hole_index = int(hole[4:]) - 1
    check("optimize_bound_held", 4.0 - 1e-9 <= new.Shape.Faces[hole_index].Surface.Radius <= 5.5 + 1e-9,
          new.Shape.Faces[hole_index].Surface.Radius)
    check("optimize_improved", new.FinalObjective < new.InitialObjective,
          (new.InitialObjective, new.FinalObjective))
    check("optimize_progress_full", panel.progress.value() == 100, panel.progress.value())
    check("optimize_status", "Wheel_optimized added" in panel.status.text(), panel.status.text())
    check("optimize_changes_listed", panel.changes.count() == 2, panel.changes.count())
    for name, label in (("history", panel.chart), ("before_after", panel.before_after)):
        check("optimize_chart_shown_" + name, label.pixmap() is not None and not label.pixmap().isNull())
    panel.charts.setCurrentIndex(1)
    dialog = panel.show_chart()
    check("optimize_chart_window", dialog is not None and dialog.isVisible())
    dialog.close()
    # Screenshot: the 3D view (original transparent, result green) and the panel's run section.
    view = FreeCADGui.getDocument(doc.Name).activeView()
    view.viewIsometric()
    view.fitAll()
    FreeCADGui.updateGui()
    view.saveImage(OPTIMIZE_VIEW, 1280, 1024, "White")
    bands = color_pixels(OPTIMIZE_VIEW)
    # Faces coloured by how far they moved: the hole by its change of radius (the shapes' own
    # radii), the untouched faces blue (0 mm), and the scale "Face moved [mm]" beside them.
    moved = list(new.FaceMoved)
    radius_change = abs(new.Shape.Faces[hole_index].Surface.Radius - part.Shape.Faces[hole_index].Surface.Radius)
    check("optimize_face_moved", len(moved) == len(new.Shape.Faces)
          and abs(moved[hole_index] - radius_change) <= 1e-6 * max(1.0, radius_change)
          and sum(m <= 1e-9 for m in moved) >= len(moved) // 2, (moved, radius_change))
    from parafab_wb import legend
    texts = legend.texts(new.ViewObject)
    check("optimize_legend", texts[-1:] == ["Face moved [mm]"] and texts[0] == "0"
          and texts[-2] == legend.format_value(max(moved)), texts)
    check("optimize_result_visible", bands["blue"] >= 2000 and sum(v >= 200 for v in bands.values()) >= 2, bands)
    scale_bands = legend_pixels(OPTIMIZE_VIEW)
    check("optimize_legend_visible", scale_bands == ("blue", "red"), scale_bands)
    cut_off = panel_cut_off(panel)  # after a run: status, parameter changes and charts filled in
    check("optimize_panel_nothing_cut_off_after_run", not cut_off, "\n" + "\n".join(cut_off))
    for key in getattr(panel, "sections", {}):
        panel.sections[key].set_expanded(key in ("constraints", "run"))
    area = scroll_area(panel.form)
    if area is not None:
        area.ensureWidgetVisible(panel.open_chart)
    FreeCADGui.updateGui()
    FreeCADGui.getMainWindow().grab().save(OPTIMIZE_SCREENSHOT)
    # Cancel a second run at its first iterate: nothing is added.
    panel.iterations.setValue(40)
    panel.run_button.click()
    panel.run.progress.connect(lambda phase, fraction: panel.cancel_button.click())
    check("optimize_cancel_finished", wait_for(lambda: panel.outcome is not None, RUN_TIMEOUT))
    check("optimize_cancel_outcome", panel.outcome.state == optimize_runner.CANCELLED, panel.outcome)
    check("optimize_cancel_nothing_added", len(doc.Objects) == len(names) + 1)
    check("optimize_cancel_progress_bar", panel.progress.format() == "cancelled", panel.progress.format())
    # Cancel sends SIGTERM: the CLI writes its best valid iterate so far (not added) and says so.
    best = panel.outcome.result or {}
    check("optimize_cancel_best_written", best.get("status") == "interrupted"
          and os.path.isfile(best.get("optimized_step", "")), panel.outcome)
    check("optimize_cancel_status_names_file", "optimized.step (not added)" in panel.status.text(), panel.status.text())
    panel.accept()
    FreeCADGui.updateGui()
    check("optimize_panel_closed", not FreeCADGui.Control.activeDialog())
    check("optimize_result_kept", doc.getObject(new.Name) is not None)
    info = {"optimize_initial": new.InitialObjective, "optimize_final": new.FinalObjective,
            "optimize_screenshot": OPTIMIZE_SCREENSHOT, "optimize_color_pixels": bands,
            "optimize_face_moved_mm": moved, "optimize_legend": texts}
    FreeCAD.closeDocument(doc.Name)
    return info


def run(check):
    """The smoke test proper; raises on the first failed check."""
    FreeCADGui.activateWorkbench("ParaFabWorkbench")
    wb = FreeCADGui.activeWorkbench()
    check("workbench_active", wb.name() == "ParaFabWorkbench", wb.name())
    check("workbench_icon", os.path.isfile(wb.Icon), wb.Icon)
    check("command_registered", "ParaFab_Strip" in FreeCADGui.listCommands())
    check("rod_command_registered", "ParaFab_Rod" in FreeCADGui.listCommands())
    check("toolbar", "ParaFab" in wb.listToolbars(), wb.listToolbars())
    check("menu", "ParaFab" in wb.listMenus(), wb.listMenus())
    tip = wb.ToolTip.lower()
    check("workbench_tooltip", all(w in tip for w in ("strips", "rods", "x-cad", "optimize")), wb.ToolTip)
    from PySide2 import QtWidgets
    FreeCADGui.updateGui()
    submenus = []
    for action in FreeCADGui.getMainWindow().menuBar().actions():
        if action.text().replace("&", "") == "ParaFab" and action.menu() is not None:
            submenus = [a.text().replace("&", "") for a in action.menu().actions()]
    check("workbench_menu", submenus == ["Bending-active strips", "Kirchhoff rods",
                                         "X-CAD analysis and shape optimization"], submenus)

    doc = FreeCAD.newDocument("GuiSmoke")
    sketch = doc.addObject("Sketcher::SketchObject", "Sketch")
    bs = Part.BSplineCurve()
    bs.interpolate([FreeCAD.Vector(x, y, 0) for x, y in
                    ((0, 0), (40, 35), (100, 50), (160, 35), (200, 0))])
    sketch.addGeometry(bs, False)
    doc.recompute()

    FreeCADGui.Selection.clearSelection()
    FreeCADGui.Selection.addSelection(doc.Name, sketch.Name, "Edge1")
    FreeCADGui.updateGui()
    FreeCADGui.runCommand("ParaFab_Strip")
    doc.recompute()

    strip = doc.getObject("Strip")
    check("strip_created", strip is not None)
    check("strip_valid", strip.isValid(), strip.getStatusString())
    check("strip_feasible", strip.Feasible, strip.Reason)
    check("strip_shape", strip.Shape.isValid() and len(strip.Shape.Solids) == 2,
          "%d solids" % len(strip.Shape.Solids))
    check("view_provider", type(strip.ViewObject.Proxy).__name__ == "ViewProviderStrip")
    check("tree_icon", os.path.isfile(strip.ViewObject.Proxy.getIcon()))
    check("undo_available", "Bending-active strip" in doc.UndoNames, doc.UndoNames)

    # Plot strip profile: K(s) and w(s) in a tab of FreeCAD's Plot module.
    check("plot_command_registered", "ParaFab_PlotStripProfile" in FreeCADGui.listCommands())
    check("stabilize_command_registered", "ParaFab_StabilizeStrip" in FreeCADGui.listCommands())
    FreeCADGui.Selection.clearSelection()
    FreeCADGui.Selection.addSelection(doc.Name, strip.Name)
    FreeCADGui.updateGui()
    FreeCADGui.runCommand("ParaFab_PlotStripProfile")
    FreeCADGui.updateGui()
    import Plot
    plot = Plot.getPlot()
    check("plot_profile_shown", plot is not None and len(plot.fig.axes) == 2
          and plot.windowTitle().startswith("Strip profile"),
          plot.windowTitle() if plot is not None else "no plot")
    # Plot strip stability: Z(s) of the Jacobi test in another Plot tab.
    check("stability_plot_command_registered", "ParaFab_PlotStripStability" in FreeCADGui.listCommands())
    FreeCADGui.runCommand("ParaFab_PlotStripStability")
    FreeCADGui.updateGui()
    zplot = Plot.getPlot()
    check("plot_stability_shown", zplot is not None and len(zplot.fig.axes) == 1
          and zplot.windowTitle().startswith("Strip stability")
          and len(zplot.fig.axes[0].lines) >= 2,  # Z(s) and the zero line
          zplot.windowTitle() if zplot is not None else "no plot")
    mdi = Plot.getMdiArea()
    for sub in mdi.subWindowList():  # back to the 3D view for the screenshot
        if sub.widget() in (plot, zplot):
            sub.close()
    FreeCADGui.updateGui()

    FreeCADGui.Selection.clearSelection()
    gui_doc = FreeCADGui.getDocument(doc.Name)
    view = gui_doc.activeView()
    view.viewIsometric()
    view.fitAll()
    FreeCADGui.updateGui()
    view.saveImage(SCREENSHOT, 1280, 1024, "White")
    check("screenshot_written", os.path.getsize(SCREENSHOT) > 0)
    pixels = strip_pixels(SCREENSHOT)
    check("strip_visible", pixels >= MIN_STRIP_PIXELS, "(%d pixels)" % pixels)
    info = {"R": strip.R, "length_mm": strip.Length.Value, "strip_pixels": pixels}

    doc.saveAs(DOCUMENT)
    FreeCAD.closeDocument(doc.Name)
    doc = FreeCAD.openDocument(DOCUMENT)
    strip = doc.getObject("Strip")
    check("reopened_view_provider",
          type(strip.ViewObject.Proxy).__name__ == "ViewProviderStrip")
    strip.touch()
    doc.recompute()
    check("reopened_recompute", strip.isValid() and strip.Feasible,
          strip.getStatusString())
    FreeCAD.closeDocument(doc.Name)
    info.update(run_analysis(check))
    info.update(run_optimize(check))
    return info


def main():
    """Run, write ``status.json``, and leave FreeCAD with the exit status."""
    check = Checks()
    status = {"status": "fail", "screenshot": SCREENSHOT}
    try:
        status["info"] = run(check)
        status["status"] = "pass"
    except Exception:
        status["error"] = traceback.format_exc()
    status["checks"] = check.results
    with open(STATUS_FILE, "w") as f:
        json.dump(status, f, indent=2)
    os._exit(0 if status["status"] == "pass" else 1)


main()
