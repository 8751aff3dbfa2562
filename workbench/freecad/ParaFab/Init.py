"""ParaFab workbench: application (non-GUI) initialisation.

FreeCAD executes this file at startup, in console and GUI mode, with this
directory on ``sys.path`` (so ``parafab_wb`` and the compiled solver module
``parafab`` are importable).  Note that ``__file__`` is undefined here in
FreeCAD 0.20.

Nothing needs registering at application level: ``Strip`` features are
created with :func:`parafab_wb.strip_feature.make_strip`, and FreeCAD imports
``parafab_wb.strip_feature`` by itself when it restores a saved document.
"""
