"""ParaFab FreeCAD workbench package.

Modules:

* :mod:`parafab_wb.geometry` -- planar edge -> exact 2D NURBS data (and back).
* :mod:`parafab_wb.shapes` -- solver result -> Part shapes (flat + bent strip).
* :mod:`parafab_wb.strip_feature` -- the ``Strip`` feature proxy, its view
  provider and :func:`~parafab_wb.strip_feature.make_strip`.
* :mod:`parafab_wb.rod_shapes`, :mod:`parafab_wb.rod_feature`, :mod:`parafab_wb.rod_plot`
  -- the ``Rod`` feature (Kirchhoff rods on space curves), its shapes and twist plot.
* :mod:`parafab_wb.analysis_feature` -- the ``Analysis`` feature (XFEM on a solid): its proxy and
  :func:`~parafab_wb.analysis_feature.make_analysis`; :mod:`parafab_wb.analysis_job` its inputs,
  solver job and results; :mod:`parafab_wb.analysis_view` its view provider (GUI only).
* :mod:`parafab_wb.result_display` -- ``surface.vtu`` -> deformed mesh coloured by von Mises.
* :mod:`parafab_wb.cli_runner` -- locate the ``parafab`` CLI and run it in a QProcess: the run
  objects (``CliProcess``, ``CliRun``, the analysis run); :mod:`parafab_wb.outcome` how a run
  ended (solved, error, cancelled).
* :mod:`parafab_wb.task_panel` -- the base of the task panels that run the CLI (GUI only);
  :mod:`parafab_wb.analysis_panel` the "Analyze part" task panel.
* :mod:`parafab_wb.optimize_feature` -- "Optimize shape" core: face model, job, the optimized
  solid added beside the original; :mod:`parafab_wb.optimize_runner` runs the CLI in a QProcess;
  :mod:`parafab_wb.optimize_panel` is its task panel (GUI only).
* :mod:`parafab_wb.commands` -- GUI commands (imported by ``InitGui.py`` only).

Layers (as in FreeCAD FEM): document objects (no Qt, no FreeCADGui at module level: FreeCAD
imports them to restore documents, also headless) <- run objects (QProcess, QtCore only) <-
view providers and task panels (Qt widgets). No import cycle, not even through an import inside a
function (tests/python/test_wb_imports.py).

This ``__init__`` must stay importable without FreeCAD: it only knows where
the icons live.  ``Init.py``/``InitGui.py`` have no ``__file__`` in FreeCAD
0.20, so they ask this package for resource paths instead.
"""

import os

_PKG_DIR = os.path.dirname(os.path.abspath(__file__))

# Installed layout: <Mod>/ParaFab/parafab_wb and <Mod>/ParaFab/Resources/icons.
# Source layout:    <repo>/workbench/freecad/ParaFab/parafab_wb and
#                   <repo>/resources/icons.
_ICON_DIRS = (
    os.path.join(_PKG_DIR, os.pardir, "Resources", "icons"),
    os.path.join(_PKG_DIR, os.pardir, os.pardir, os.pardir, os.pardir,
                 "resources", "icons"),
)


def icon_path(name):
    """Return the absolute path of icon ``name`` or ``""`` when not found.

    FreeCAD accepts an empty pixmap path and shows a default icon, so a
    missing icon never breaks the workbench.
    """
    for directory in _ICON_DIRS:
        path = os.path.normpath(os.path.join(directory, name))
        if os.path.isfile(path):
            return path
    return ""
