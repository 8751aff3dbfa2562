"""ParaFab workbench: GUI initialisation (toolbar, menu, icon).

FreeCAD executes this file in GUI mode with this directory on ``sys.path``.
``__file__`` is undefined here in FreeCAD 0.20, so the icon path comes from
the ``parafab_wb`` package (see :func:`parafab_wb.icon_path`).
"""

import FreeCADGui


class ParaFabWorkbench(FreeCADGui.Workbench):
    """Workbench for designing bending-active strips on planar curves."""

    MenuText = "ParaFab"
    ToolTip = "Design bending-active strips on planar curves"
    Icon = ""

    #: Commands shown in the toolbar and the menu.
    COMMANDS = ["ParaFab_Strip", "ParaFab_StripsFromSections", "ParaFab_RevolutionStrips",
                "ParaFab_ExportCutSheets", "ParaFab_PlotStripProfile", "ParaFab_PlotStripStability",
                "ParaFab_ImproveFabricability",
                "ParaFab_StabilizeStrip", "ParaFab_Rod", "ParaFab_AnalyzePart", "ParaFab_OptimizeShape"]

    def __init__(self):
        import parafab_wb
        self.__class__.Icon = parafab_wb.icon_path("ParaFab_Workbench.svg")

    def Initialize(self):
        """Called on first activation: register commands, build the UI."""
        import parafab_wb.commands  # noqa: F401  (registers the commands)
        self.appendToolbar("ParaFab", self.COMMANDS)
        self.appendMenu("ParaFab", self.COMMANDS)

    def Activated(self):
        """Called when the workbench is activated."""

    def Deactivated(self):
        """Called when another workbench is activated."""

    def GetClassName(self):
        """C++ class backing this Python workbench."""
        return "Gui::PythonWorkbench"


FreeCADGui.addWorkbench(ParaFabWorkbench())
