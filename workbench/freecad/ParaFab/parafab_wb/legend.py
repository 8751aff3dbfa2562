"""Colour scale (legend) of a coloured result, drawn over the 3D view (GUI only).

FreeCAD 0.20's Part and Mesh objects have no colour bar of their own, so this module adds one
to the object's own Coin scene graph: a vertical bar with the colours of
:data:`result_display.COLOR_STOPS`, a title with the unit (e.g. ``von Mises [MPa]``) and a
tick label at each stop (the smallest value at the bottom, the largest at the top). It sits at
the left edge of the view, in screen coordinates (its own ``SoOrthographicCamera`` in an
``SoAnnotation``, so it is drawn on top and neither turns nor zooms with the part), is not
pickable, and is left out of "Fit all" (FreeCAD's ``SoSkipBoundingGroup``). The legend node is
put under each display mode of the object's ``SwitchNode``, so it shows exactly while the
object is visible, in every display mode, and is in ``view.saveImage`` screenshots.

:func:`show` adds or replaces the legend of a view object, :func:`remove` takes it away,
:func:`texts` returns its strings (for tests and scripts).
"""

#: Name of the legend's top node (to find and replace it).
NODE_NAME = "ParaFabColorLegend"
#: Where the bar sits in normalized view coordinates (-1..1 both ways, the view's left edge at -1).
BAR_X = (-0.96, -0.93)
BAR_Y = (-0.55, 0.55)
TEXT_COLOR = (0.05, 0.05, 0.05)
FONT_SIZE = 14


def _add(parent, group, *nodes):
    """``nodes`` into ``group``, and ``group`` into ``parent``."""
    for node in nodes:
        group.addChild(node)
    parent.addChild(group)

def tick_values(lo, hi, count):
    """``count`` evenly spaced values from ``lo`` to ``hi`` (both included)."""
    if count < 2:
        return [lo]
    return [lo + (hi - lo) * i / (count - 1) for i in range(count)]


def format_value(value):
    """A tick label: four significant digits, no exponent between 1e-3 and 1e5."""
    if value == 0:
        return "0"
    return "%.4g" % value


def _mode_groups(vobj):
    switch = getattr(vobj, "SwitchNode", None)
    if switch is None:
        return []
    return [switch.getChild(i) for i in range(switch.getNumChildren())]


def _find(group):
    from pivy import coin
    for i in range(group.getNumChildren()):
        child = group.getChild(i)
        if child.getName() == coin.SbName(NODE_NAME):
            return child
    return None


def _text(coin, x, y, string, justification):
    sep = coin.SoSeparator()
    move = coin.SoTranslation()
    move.translation.setValue(x, y, 0)
    text = coin.SoText2()
    text.string.setValue(string)
    text.justification = justification
    sep.addChild(move)
    sep.addChild(text)
    return sep


def build(title, lo, hi, stops):
    """The legend node: ``title`` above a bar coloured by ``stops`` (RGB, lowest first) with
    the values from ``lo`` to ``hi`` at the stops."""
    from pivy import coin
    skip = coin.SoType.fromName("SoSkipBoundingGroup").createInstance()  # FreeCAD's, left out of Fit all
    skip.set("mode EXCLUDE_BBOX")
    skip.setName(NODE_NAME)
    overlay = coin.SoAnnotation()
    skip.addChild(overlay)
    pick = coin.SoPickStyle()
    pick.style = coin.SoPickStyle.UNPICKABLE
    overlay.addChild(pick)
    camera = coin.SoOrthographicCamera()
    camera.viewportMapping = coin.SoCamera.LEAVE_ALONE  # -1..1 is the whole view, whatever its shape
    camera.position.setValue(0, 0, 5)
    camera.height = 2.0
    camera.nearDistance = 1.0
    camera.farDistance = 10.0
    overlay.addChild(camera)
    light = coin.SoLightModel()
    light.model = coin.SoLightModel.BASE_COLOR
    overlay.addChild(light)

    n = len(stops)
    x0, x1 = BAR_X
    y0, y1 = BAR_Y
    ys = tick_values(y0, y1, n)
    bar = coin.SoSeparator()
    material = coin.SoMaterial()
    material.diffuseColor.setValues(0, 2 * n, [c for c in stops for _ in (0, 1)])
    binding = coin.SoMaterialBinding()
    binding.value = coin.SoMaterialBinding.PER_VERTEX_INDEXED
    coords = coin.SoCoordinate3()
    coords.point.setValues(0, 2 * n, [p for y in ys for p in ((x0, y, 0), (x1, y, 0))])
    faces = coin.SoIndexedFaceSet()
    index = []
    for i in range(n - 1):
        index += [2 * i, 2 * i + 1, 2 * i + 3, 2 * i + 2, -1]
    faces.coordIndex.setValues(0, len(index), index)
    faces.materialIndex.setValues(0, len(index), index)
    _add(overlay, bar, material, binding, coords, faces)

    frame = coin.SoSeparator()
    frame_color = coin.SoBaseColor()
    frame_color.rgb = TEXT_COLOR
    frame_coords = coin.SoCoordinate3()
    corners = [(x0, y0, 0), (x1, y0, 0), (x1, y1, 0), (x0, y1, 0), (x0, y0, 0)]
    ticks = [p for y in ys for p in ((x1, y, 0), (x1 + 0.008, y, 0))]
    frame_coords.point.setValues(0, len(corners) + len(ticks), corners + ticks)
    lines = coin.SoLineSet()
    lines.numVertices.setValues(0, 1 + n, [len(corners)] + [2] * n)
    _add(overlay, frame, frame_color, frame_coords, lines)

    labels = coin.SoSeparator()
    color = coin.SoBaseColor()
    color.rgb = TEXT_COLOR
    font = coin.SoFont()
    font.name = "sans"
    font.size = FONT_SIZE
    labels.addChild(color)
    labels.addChild(font)
    for y, value in zip(ys, tick_values(lo, hi, n)):
        labels.addChild(_text(coin, x1 + 0.014, y - 0.012, format_value(value), coin.SoText2.LEFT))
    labels.addChild(_text(coin, x0, y1 + 0.05, title, coin.SoText2.LEFT))
    overlay.addChild(labels)
    return skip


def remove(vobj):
    """Take the legend off view object ``vobj`` (nothing when it has none)."""
    for group in _mode_groups(vobj):
        node = _find(group)
        if node is not None:
            group.removeChild(node)


def show(vobj, title, lo, hi, stops):
    """Add (or replace) the legend of view object ``vobj``: ``title`` (with the unit, e.g.
    ``"von Mises [MPa]"``) and the scale from ``lo`` to ``hi`` on ``stops``. Returns the node,
    or ``None`` when ``vobj`` has no display modes."""
    groups = _mode_groups(vobj)
    if not groups:
        return None
    remove(vobj)
    node = build(title, lo, hi, stops)
    for group in groups:
        group.addChild(node)
    return node


def texts(vobj):
    """The strings of the legend of ``vobj``: tick labels from the bottom, then the title;
    ``[]`` without a legend."""
    from pivy import coin
    for group in _mode_groups(vobj):
        node = _find(group)
        if node is None:
            continue
        search = coin.SoSearchAction()
        search.setType(coin.SoText2.getClassTypeId())
        search.setInterest(coin.SoSearchAction.ALL)
        search.setSearchingAll(True)
        search.apply(node)
        paths = search.getPaths()
        return [paths[i].getTail().string.getValues()[0] for i in range(paths.getLength())]
    return []
