"""ParaFab workbench: GUI initialisation (toolbar, menu, icon).

FreeCAD executes this file in GUI mode with this directory on ``sys.path``.
``__file__`` is undefined here in FreeCAD 0.20, so the icon path comes from
the ``parafab_wb`` package (see :func:`parafab_wb.icon_path`).
"""

import FreeCADGui


class ParaFabWorkbench(FreeCADGui.Workbench):
    """Workbench of the ParaFab plug-ins: bending-active strips on planar curves, Kirchhoff rods
    on space curves, X-CAD analysis (XFEM on the B-rep) and shape optimization of solids."""

    MenuText = "ParaFab"
    ToolTip = ("Design bending-active strips and Kirchhoff rods from curves, analyse solids with X-CAD "
               "(XFEM on the B-rep: stress and displacement) and optimize their shape on their own CAD "
               "parameters")
    Icon = ""

    #: The commands by capability: (submenu of the ParaFab menu, commands).
    GROUPS = [
        ("Bending-active strips", ["ParaFab_Strip", "ParaFab_StripsFromSections", "ParaFab_RevolutionStrips",
                                   "ParaFab_ExportCutSheets", "ParaFab_PlotStripProfile",
                                   "ParaFab_PlotStripStability", "ParaFab_ImproveFabricability",
                                   "ParaFab_StabilizeStrip"]),
        ("Kirchhoff rods", ["ParaFab_Rod"]),
        ("X-CAD analysis and shape optimization", ["ParaFab_AnalyzePart", "ParaFab_OptimizeShape"]),
    ]
    #: Commands shown in the toolbar and the menu.
    COMMANDS = [c for _, commands in GROUPS for c in commands]

    def __init__(self):
        import parafab_wb
        self.__class__.Icon = parafab_wb.icon_path("ParaFab_Workbench.svg")

    def Initialize(self):
        """Called on first activation: register commands, build the UI."""
        import parafab_wb.commands  # noqa: F401  (registers the commands)
        toolbar = []
        for title, commands in self.GROUPS:
            toolbar += (["Separator"] if toolbar else []) + commands
            self.appendMenu(["ParaFab", title], commands)
        self.appendToolbar("ParaFab", toolbar)

    def Activated(self):
        """Called when the workbench is activated."""

    def Deactivated(self):
        """Called when another workbench is activated."""

    def GetClassName(self):
        """C++ class backing this Python workbench."""
        return "Gui::PythonWorkbench"


FreeCADGui.addWorkbench(ParaFabWorkbench())
