"""View provider of the ``Analysis`` feature (GUI only, as FreeCAD FEM keeps its view providers
apart from its document objects): tree icon, the result mesh as its child, the colour scale put
back on reopening, and the task panel (:mod:`parafab_wb.analysis_panel`) on double-click.

Imported by :mod:`parafab_wb.analysis_feature` only when the GUI is up (and by FreeCAD when it
restores a document's view); FreeCADGui and the panel are imported where they are used.
"""

from . import feature_proxy
from . import result_display


class ViewProviderAnalysis(feature_proxy.IconViewProvider):
    """View provider of the ``Analysis`` feature (GUI only): icon, the result mesh as its child,
    and the task panel on double-click."""

    ICON = "ParaFab_Analysis.svg"

    def claimChildren(self):
        mesh = getattr(self.Object, "ResultMesh", None)
        return [mesh] if mesh is not None else []

    def updateData(self, obj, prop):
        # The colour scale lives in the view only: put it back when a document is reopened.
        if prop in ("ResultMesh", "ColorScaleMax"):
            result_display.show_legend(getattr(obj, "ResultMesh", None))

    def finishRestoring(self):
        obj = getattr(self, "Object", None)
        if obj is not None:
            result_display.show_legend(getattr(obj, "ResultMesh", None))

    def setEdit(self, vobj, mode=0):
        if mode != 0:
            return None
        from . import analysis_panel
        return analysis_panel.open_panel(vobj.Object)

    def unsetEdit(self, vobj, mode=0):
        if mode != 0:
            return None
        import FreeCADGui
        FreeCADGui.Control.closeDialog()
        return True

    def doubleClicked(self, vobj):
        import FreeCADGui
        FreeCADGui.getDocument(vobj.Object.Document.Name).setEdit(vobj.Object.Name, 0)
        return True

    def onDelete(self, vobj, subelements):
        mesh = getattr(vobj.Object, "ResultMesh", None)
        if mesh is not None:
            vobj.Object.ResultMesh = None
            mesh.Document.removeObject(mesh.Name)
        return True
