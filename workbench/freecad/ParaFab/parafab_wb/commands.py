"""GUI commands of the ParaFab workbench.

Importing this module registers the commands with ``FreeCADGui.addCommand``;
``InitGui.py`` does so when the workbench is first activated.

* ``ParaFab_Strip`` -- "Bending-active strip": create a ``Strip`` feature on
  the selected planar edge (sketch B-spline, arc, ellipse arc, Part edge).
* ``ParaFab_Rod`` -- "Kirchhoff rod": create a ``Rod`` feature on the selected
  space-curve edge; export both rods with ``parafab_wb.rod_feature.export_step``
  and the twist plot with ``write_twist_plot`` (or set its ``PlotFile``).
* ``ParaFab_ExportCutSheets`` -- "Export cut sheets": DXF and SVG outlines of the
  selected strips (:func:`parafab_wb.strip_feature.export_cut_sheets`).
* ``ParaFab_PlotStripProfile`` -- "Plot strip profile": K(s) and w(s) of the selected
  strips in FreeCAD's Plot module (:func:`parafab_wb.strip_feature.plot_profile`).
* ``ParaFab_ImproveFabricability`` -- "Improve fabricability": lower R of the selected
  strips to a target by moving their curves' control points, in one undo transaction, the
  original kept hidden (:mod:`parafab_wb.strip_improve`), and plot the curve before and after.
* ``ParaFab_StabilizeStrip`` -- "Stabilize strip": move the control points of the selected
  strips' curves until they are stable (thesis 4.5.4, Algorithm 4.2), in one undo
  transaction, the original kept hidden (:mod:`parafab_wb.strip_stabilize`).
* ``ParaFab_AnalyzePart`` -- "Analyze part": create an ``Analysis`` of the selected
  solid (selected faces fixed) and open its task panel (:mod:`parafab_wb.analysis_panel`).
* ``ParaFab_OptimizeShape`` -- "Optimize shape": open the shape-optimization task panel on the
  selected solid (selected faces' offsets/radii checked as design parameters); the result is a
  new solid beside the original (:mod:`parafab_wb.optimize_panel`, :mod:`parafab_wb.optimize_feature`).
"""

import FreeCAD
import FreeCADGui

from . import icon_path
from . import strip_feature


def selected_edge():
    """``(object, "EdgeN")`` of the first selected edge, or ``None``."""
    for sel in FreeCADGui.Selection.getSelectionEx():
        for name in sel.SubElementNames:
            # Sub-element names may carry a path prefix ("Sketch.Edge1").
            element = name.split(".")[-1]
            if element.startswith("Edge"):
                return sel.Object, element
    return None


def in_transaction(doc, title, action):
    """Run ``action()`` inside the undo transaction ``title``; on failure, undo it and print
    the error (the document stays as it was). Returns the action's result, or None."""
    doc.openTransaction(title)
    try:
        result = action()
    except Exception as exc:
        doc.abortTransaction()
        FreeCAD.Console.PrintError("ParaFab: %s failed: %s\n" % (title, exc))
        return None
    doc.commitTransaction()
    return result


class EdgeFeatureCommand(object):
    """A command that creates a feature on the selected edge (strip, rod)."""

    RESOURCES = {}
    TITLE = ""

    def make(self, owner, element, doc):
        raise NotImplementedError

    def GetResources(self):
        """Icon, menu text and tooltip."""
        return self.RESOURCES

    def IsActive(self):
        """Enabled when a document is open and an edge is selected."""
        return FreeCAD.ActiveDocument is not None and selected_edge() is not None

    def Activated(self):
        """Create and recompute the feature inside an undo transaction."""
        selection = selected_edge()
        if selection is None:
            FreeCAD.Console.PrintError("ParaFab: select an edge first\n")
            return
        owner, element = selection
        doc = owner.Document

        def create():
            self.make(owner, element, doc)
            doc.recompute()
        in_transaction(doc, self.TITLE, create)


class StripCommand(EdgeFeatureCommand):
    """Create a bending-active strip on the selected edge."""

    TITLE = "Bending-active strip"
    RESOURCES = {
        "Pixmap": icon_path("ParaFab_Strip.svg"),
        "MenuText": "Bending-active strip",
        "ToolTip": "Design a bending-active strip whose bent shape follows the selected planar edge",
    }

    def make(self, owner, element, doc):
        strip_feature.make_strip(owner, element, doc)


FreeCADGui.addCommand("ParaFab_Strip", StripCommand())


class RodCommand(EdgeFeatureCommand):
    """Create a Kirchhoff rod on the selected space-curve edge."""

    TITLE = "Kirchhoff rod"
    RESOURCES = {
        "Pixmap": icon_path("ParaFab_Rod.svg"),
        "MenuText": "Kirchhoff rod",
        "ToolTip": "Design a Kirchhoff rod (elliptical sections, twist, clamped end frames) whose "
                   "equilibrium follows the selected 3D edge. The shape holds the deformed and the "
                   "straight rod; export both as STEP with parafab_wb.rod_feature.export_step(obj, path)",
    }

    def make(self, owner, element, doc):
        from . import rod_feature
        rod_feature.make_rod(owner, element, doc)


FreeCADGui.addCommand("ParaFab_Rod", RodCommand())


def selected_strips():
    """Selected ``Strip`` features."""
    return [sel.Object for sel in FreeCADGui.Selection.getSelectionEx()
            if getattr(getattr(sel.Object, "Proxy", None), "Type", None) == strip_feature.TYPE]


class ExportCutSheetsCommand(object):
    """Write the flat outlines of the selected strips as DXF and SVG (true scale, mm)."""

    def GetResources(self):
        return {
            "Pixmap": icon_path("ParaFab_ExportCutSheets.svg"),
            "MenuText": "Export cut sheets",
            "ToolTip": "Write the flat outline of each selected strip (true scale, mm; both "
                       "layers of composite strips, holes of perforated ones; clamp positions "
                       "and end angles annotated) as <Label>.dxf and <Label>.svg",
        }

    def IsActive(self):
        return FreeCAD.ActiveDocument is not None and bool(selected_strips())

    def Activated(self):
        from PySide import QtGui
        strips = selected_strips()
        directory = QtGui.QFileDialog.getExistingDirectory(
            FreeCADGui.getMainWindow(), "Folder for the cut sheets (DXF, SVG)")
        if not directory:
            return
        for obj in strips:
            try:
                for path in strip_feature.export_cut_sheets(obj, directory):
                    FreeCAD.Console.PrintMessage("ParaFab: wrote %s\n" % path)
            except Exception as exc:
                FreeCAD.Console.PrintError("ParaFab: %s: %s\n" % (obj.Label, exc))


FreeCADGui.addCommand("ParaFab_ExportCutSheets", ExportCutSheetsCommand())


class PlotSelectedStripsCommand(object):
    """Base of the plot commands: ``plot(obj)`` for each selected strip, errors reported; a
    subclass gives its ICON, MENU and TOOLTIP."""

    ICON = MENU = TOOLTIP = None

    def GetResources(self):
        return {"Pixmap": icon_path(self.ICON), "MenuText": self.MENU, "ToolTip": self.TOOLTIP}

    def plot(self, obj):
        raise NotImplementedError

    def IsActive(self):
        return FreeCAD.ActiveDocument is not None and bool(selected_strips())

    def Activated(self):
        for obj in selected_strips():
            try:
                self.plot(obj)
            except Exception as exc:
                import traceback
                FreeCAD.Console.PrintLog(traceback.format_exc())
                FreeCAD.Console.PrintError("ParaFab: %s: %s\n" % (obj.Label, exc))


class PlotStripProfileCommand(PlotSelectedStripsCommand):
    """Plot K(s) and w(s) of the selected strips in FreeCAD's Plot module."""

    ICON = "ParaFab_PlotStripProfile.svg"
    MENU = "Plot strip profile"
    TOOLTIP = "Plot the stiffness profile K(s) and the width w(s) of each selected strip (a Plot tab per strip)"

    def plot(self, obj):
        strip_feature.plot_profile(obj, show=True)


FreeCADGui.addCommand("ParaFab_PlotStripProfile", PlotStripProfileCommand())


class PlotStripStabilityCommand(PlotSelectedStripsCommand):
    """Plot Z(s) of the selected strips (the Jacobi test, thesis 4.5) in FreeCAD's Plot module."""

    ICON = "ParaFab_PlotStripStability.svg"
    MENU = "Plot strip stability"
    TOOLTIP = ("Plot the stability determinant Z(s) of each selected strip, its first conjugate point sigma "
               "marked when the strip is unstable (thesis 4.5; a Plot tab per strip)")

    def plot(self, obj):
        strip_feature.plot_stability(obj, show=True)


FreeCADGui.addCommand("ParaFab_PlotStripStability", PlotStripStabilityCommand())


class ImproveFabricabilityCommand(object):
    """Lower the stiffness ratio R of the selected strips by moving their curves' poles."""

    def GetResources(self):
        return {
            "Pixmap": icon_path("ParaFab_ImproveStrip.svg"),
            "MenuText": "Improve fabricability",
            "ToolTip": "Move the control points of each selected strip's curve until its stiffness "
                       "ratio R is at most the target (thesis 4.6.2). One undo step; the original "
                       "curve is kept hidden (property OriginalCurve); plots the curve before and after",
        }

    def IsActive(self):
        return FreeCAD.ActiveDocument is not None and bool(selected_strips())

    def Activated(self):
        from PySide import QtGui
        from . import strip_improve
        target, ok = QtGui.QInputDialog.getDouble(
            FreeCADGui.getMainWindow(), "Improve fabricability", "Target stiffness ratio R:", 3.5, 1.0, 1000.0, 2)
        if not ok:
            return
        for obj in selected_strips():
            try:
                result = strip_improve.improve_strip(obj, target)
                FreeCAD.Console.PrintMessage(
                    "ParaFab: %s: R %.4g -> %.4g (%s), max pole move %.3g mm, deviation %.3g mm\n" % (
                        obj.Label, result["R_initial"] or 0, result["R"] or 0, result["status"],
                        result["max_pole_move"] * 1e3, result["deviation"] * 1e3))
                strip_improve.plot_improvement(result, show=True, title=obj.Label)
            except Exception as exc:
                FreeCAD.Console.PrintError("ParaFab: %s: %s\n" % (obj.Label, exc))


FreeCADGui.addCommand("ParaFab_ImproveFabricability", ImproveFabricabilityCommand())


class StabilizeStripCommand(object):
    """Make the selected strips stable by moving their curves' poles (Algorithm 4.2)."""

    def GetResources(self):
        return {
            "Pixmap": icon_path("ParaFab_StabilizeStrip.svg"),
            "MenuText": "Stabilize strip",
            "ToolTip": "Move the control points of each selected strip's curve until the strip is a "
                       "stable equilibrium (no conjugate point up to its end, thesis 4.5.4), keeping "
                       "the stiffness ratio R at most R_max. One undo step; the original curve is kept "
                       "hidden (property OriginalCurve); plots the curve and the conjugate point before "
                       "and after. Gravity is neglected",
        }

    def IsActive(self):
        return FreeCAD.ActiveDocument is not None and bool(selected_strips())

    def Activated(self):
        from PySide import QtGui
        from . import strip_stabilize
        R_max, ok = QtGui.QInputDialog.getDouble(
            FreeCADGui.getMainWindow(), "Stabilize strip", "Bound on the stiffness ratio R:", 10.0, 1.0, 1000.0, 2)
        if not ok:
            return
        for obj in selected_strips():
            try:
                result = strip_stabilize.stabilize_strip(obj, R_max)
                FreeCAD.Console.PrintMessage(strip_stabilize.report(obj.Label, result))
                if result["status"] != "already":
                    strip_stabilize.plot_stabilization(result, show=True, title=obj.Label)
            except Exception as exc:
                FreeCAD.Console.PrintError("ParaFab: %s: %s\n" % (obj.Label, exc))


FreeCADGui.addCommand("ParaFab_StabilizeStrip", StabilizeStripCommand())


class StripsFromSectionsCommand(object):
    """Strips from plane sections of the selected surface or solid (§4.8.2)."""

    def GetResources(self):
        return {
            "Pixmap": icon_path("ParaFab_StripsFromSections.svg"),
            "MenuText": "Strips from sections",
            "ToolTip": "Cut the selected surface or solid by 5 planes across its longest side, split every "
                       "section at the middle plane of the shortest side, and design a strip on each piece",
        }

    def IsActive(self):
        sel = FreeCADGui.Selection.getSelection()
        return bool(sel) and hasattr(sel[0], "Shape") and bool(sel[0].Shape.Faces)

    def Activated(self):
        from . import sections
        obj = FreeCADGui.Selection.getSelection()[0]
        box = obj.Shape.BoundBox
        lengths = [box.XLength, box.YLength, box.ZLength]
        longest = lengths.index(max(lengths))
        shortest = lengths.index(min(lengths))
        if shortest == longest:
            shortest = (longest + 1) % 3
        normal = [1.0 if a == longest else 0.0 for a in range(3)]
        split_normal = [1.0 if a == shortest else 0.0 for a in range(3)]
        split_offset = [box.Center.x, box.Center.y, box.Center.z][shortest]
        doc = obj.Document
        done = in_transaction(doc, "Strips from sections", lambda: sections.strips_from_sections(
            obj, normal, 5, split=(split_normal, split_offset)))
        if done is None:
            return
        report = done[1]
        FreeCAD.Console.PrintMessage("ParaFab: %d strips designed, %d infeasible, %d failed\n"
                                     % (report["designed"], report["infeasible"], report["failed"]))


FreeCADGui.addCommand("ParaFab_StripsFromSections", StripsFromSectionsCommand())


class RevolutionStripsCommand(object):
    """A surface of revolution covered by strips without gaps (§4.8.4); edit the meridian's
    a, b, start and length and the strip count in the property editor."""

    def GetResources(self):
        return {
            "Pixmap": icon_path("ParaFab_RevolutionStrips.svg"),
            "MenuText": "Surface of revolution strips",
            "ToolTip": "A surface of revolution whose meridian solves x·κ = a + ⟨b, γ⟩, covered by n "
                       "strips without gaps, with their flat outlines",
        }

    def IsActive(self):
        return FreeCAD.ActiveDocument is not None

    def Activated(self):
        from . import revolution_feature
        doc = FreeCAD.ActiveDocument
        in_transaction(doc, "Surface of revolution strips",
                       lambda: (revolution_feature.make_revolution_strips(doc), doc.recompute()))


FreeCADGui.addCommand("ParaFab_RevolutionStrips", RevolutionStripsCommand())


class AnalyzePartCommand(object):
    """Analyze the selected solid: creates an ``Analysis`` feature (selected faces held fixed)
    and opens its task panel, where loads, material and grid are set and the run is started."""

    def GetResources(self):
        return {
            "Pixmap": icon_path("ParaFab_Analysis.svg"),
            "MenuText": "Analyze part",
            "ToolTip": "Linear or hyperelastic XFEM simulation of the selected solid on a fixed grid; "
                       "selected faces are held fixed, the rest is set in the task panel",
        }

    def IsActive(self):
        sel = FreeCADGui.Selection.getSelectionEx()
        return bool(sel) and hasattr(sel[0].Object, "Shape") and bool(sel[0].Object.Shape.Solids) \
            and not FreeCADGui.Control.activeDialog()

    def Activated(self):
        from . import analysis_feature
        sel = FreeCADGui.Selection.getSelectionEx()[0]
        faces = [n.split(".")[-1] for n in sel.SubElementNames if n.split(".")[-1].startswith("Face")]
        doc = sel.Object.Document
        # One transaction for the new feature and the task panel: the panel's Cancel undoes both.
        doc.openTransaction("Analyze part")
        try:
            obj = analysis_feature.make_analysis(sel.Object, faces)
        except Exception as exc:
            doc.abortTransaction()
            FreeCAD.Console.PrintError("ParaFab: cannot create analysis: %s\n" % exc)
            return
        FreeCADGui.Selection.clearSelection()
        FreeCADGui.getDocument(doc.Name).setEdit(obj.Name, 0)


FreeCADGui.addCommand("ParaFab_AnalyzePart", AnalyzePartCommand())


class OptimizeShapeCommand(object):
    """Optimize the selected solid on its own face parameters (tangencies kept, thesis §6.5):
    opens the task panel; the optimized solid is added beside the original."""

    def GetResources(self):
        return {
            "Pixmap": icon_path("ParaFab_OptimizeShape.svg"),
            "MenuText": "Optimize shape",
            "ToolTip": "Shape optimization of the selected solid on its plane offsets, radii and axes, "
                       "keeping its tangencies (e.g. balance it about an axis); selected faces start as "
                       "design parameters; the result is a new solid beside the original",
        }

    def IsActive(self):
        sel = FreeCADGui.Selection.getSelectionEx()
        return bool(sel) and hasattr(sel[0].Object, "Shape") and bool(sel[0].Object.Shape.Solids) \
            and not FreeCADGui.Control.activeDialog()

    def Activated(self):
        from . import optimize_feature, optimize_panel
        sel = FreeCADGui.Selection.getSelectionEx()[0]
        try:
            optimize_feature.solid_shape(sel.Object)
        except optimize_feature.OptimizeError as exc:
            FreeCAD.Console.PrintError("ParaFab: cannot optimize: %s\n" % exc)
            return
        faces = [n.split(".")[-1] for n in sel.SubElementNames if n.split(".")[-1].startswith("Face")]
        FreeCADGui.Selection.clearSelection()
        optimize_panel.open_panel(sel.Object, faces)


FreeCADGui.addCommand("ParaFab_OptimizeShape", OptimizeShapeCommand())
