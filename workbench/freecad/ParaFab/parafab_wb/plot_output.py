"""One place for ParaFab's plots: a drawing function ``draw(fig) -> axes`` rendered to a PNG
(headless, matplotlib's Agg canvas, no pyplot state) and/or into a tab of FreeCAD's Plot module.

Works headless; imports FreeCAD's ``Plot`` only when a plot is shown (it sets matplotlib's Qt
backend: GUI only)."""

import FreeCAD


def render(draw, png_path=None, show=None, figsize=(8, 4), window_title="ParaFab"):
    """Draw into a PNG at ``png_path`` (when given) and into the Plot tab ``window_title`` when
    ``show`` (default: when the GUI is up). Returns ``png_path``."""
    if png_path:
        from matplotlib.figure import Figure
        from matplotlib.backends.backend_agg import FigureCanvasAgg
        fig = Figure(figsize=figsize)
        FigureCanvasAgg(fig)
        draw(fig)
        fig.tight_layout()
        fig.savefig(png_path, dpi=100)
    if show is None:
        show = FreeCAD.GuiUp
    if show:
        try:
            import Plot
        except ImportError as exc:
            FreeCAD.Console.PrintWarning("ParaFab: FreeCAD's Plot module is not available (%s)\n" % exc)
            return png_path
        win = Plot.figure(window_title)
        if win is not None:
            # Not fig.clf(): with matplotlib 3.6 it updates the Plot tab's toolbar, whose
            # actions PySide has already deleted (RuntimeError).
            for ax in list(win.fig.axes):
                win.fig.delaxes(ax)
            axes = draw(win.fig)
            axes = list(axes) if isinstance(axes, (list, tuple)) else [axes]
            win.axes, win.axesList = axes[0], axes
            win.fig.tight_layout()
            win.update()
    return png_path
