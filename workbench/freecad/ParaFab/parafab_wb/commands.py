"""GUI commands of the ParaFab workbench.

Importing this module registers the commands with ``FreeCADGui.addCommand``;
``InitGui.py`` does so when the workbench is first activated.

* ``ParaFab_Strip`` -- "Bending-active strip": create a ``Strip`` feature on
  the selected planar edge (sketch B-spline, arc, ellipse arc, Part edge).
* ``ParaFab_Rod`` -- "Kirchhoff rod": create a ``Rod`` feature on the selected
  space-curve edge; export both rods with ``parafab_wb.rod_feature.export_step``
  and the twist plot with ``write_twist_plot`` (or set its ``PlotFile``).
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


class StripCommand(object):
    """Create a bending-active strip on the selected edge."""

    def GetResources(self):
        """Icon, menu text and tooltip."""
        return {
            "Pixmap": icon_path("ParaFab_Strip.svg"),
            "MenuText": "Bending-active strip",
            "ToolTip": "Design a bending-active strip whose bent shape follows "
                       "the selected planar edge",
        }

    def IsActive(self):
        """Enabled when a document is open and an edge is selected."""
        return FreeCAD.ActiveDocument is not None and selected_edge() is not None

    def Activated(self):
        """Create and recompute the strip inside an undo transaction."""
        selection = selected_edge()
        if selection is None:
            FreeCAD.Console.PrintError("ParaFab: select a planar edge first\n")
            return
        owner, element = selection
        doc = owner.Document
        doc.openTransaction("Bending-active strip")
        try:
            strip_feature.make_strip(owner, element, doc)
            doc.recompute()
        except Exception as exc:
            doc.abortTransaction()
            FreeCAD.Console.PrintError("ParaFab: cannot create strip: %s\n" % exc)
            return
        doc.commitTransaction()


FreeCADGui.addCommand("ParaFab_Strip", StripCommand())


class RodCommand(object):
    """Create a Kirchhoff rod on the selected space-curve edge."""

    def GetResources(self):
        return {
            "Pixmap": icon_path("ParaFab_Rod.svg"),
            "MenuText": "Kirchhoff rod",
            "ToolTip": "Design a Kirchhoff rod (elliptical sections, twist, clamped end frames) whose "
                       "equilibrium follows the selected 3D edge. The shape holds the deformed and the "
                       "straight rod; export both as STEP with parafab_wb.rod_feature.export_step(obj, path)",
        }

    def IsActive(self):
        return FreeCAD.ActiveDocument is not None and selected_edge() is not None

    def Activated(self):
        from . import rod_feature
        selection = selected_edge()
        if selection is None:
            FreeCAD.Console.PrintError("ParaFab: select an edge first\n")
            return
        owner, element = selection
        doc = owner.Document
        doc.openTransaction("Kirchhoff rod")
        try:
            rod_feature.make_rod(owner, element, doc)
            doc.recompute()
        except Exception as exc:
            doc.abortTransaction()
            FreeCAD.Console.PrintError("ParaFab: cannot create rod: %s\n" % exc)
            return
        doc.commitTransaction()


FreeCADGui.addCommand("ParaFab_Rod", RodCommand())


class AnalyzePartCommand(object):
    """Analyze the selected solid: the selected faces are held fixed; loads (LoadedFaces,
    Force), material and grid are set in the property editor, then the feature recomputes."""

    def GetResources(self):
        return {
            "Pixmap": icon_path("ParaFab_Analysis.svg"),
            "MenuText": "Analyze part",
            "ToolTip": "Linear or hyperelastic XFEM simulation of the selected solid on a fixed grid; "
                       "selected faces are held fixed",
        }

    def IsActive(self):
        sel = FreeCADGui.Selection.getSelectionEx()
        return bool(sel) and hasattr(sel[0].Object, "Shape") and bool(sel[0].Object.Shape.Solids)

    def Activated(self):
        from . import analysis_feature
        sel = FreeCADGui.Selection.getSelectionEx()[0]
        faces = [n.split(".")[-1] for n in sel.SubElementNames if n.split(".")[-1].startswith("Face")]
        doc = sel.Object.Document
        doc.openTransaction("Analyze part")
        try:
            analysis_feature.make_analysis(sel.Object, faces)
        except Exception as exc:
            doc.abortTransaction()
            FreeCAD.Console.PrintError("ParaFab: cannot create analysis: %s\n" % exc)
            return
        doc.commitTransaction()
        FreeCAD.Console.PrintMessage(
            "ParaFab: analysis created; set LoadedFaces and Force, then recompute\n")


FreeCADGui.addCommand("ParaFab_AnalyzePart", AnalyzePartCommand())
