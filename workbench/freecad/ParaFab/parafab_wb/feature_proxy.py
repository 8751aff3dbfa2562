"""Shared plumbing of ParaFab's ``Part::FeaturePython`` proxies: typed properties from a
table, and proxy state that survives save/reload (FreeCAD 0.20 stores what
``__getstate__`` returns as JSON; 0.21 calls ``dumps``/``loads``).
"""

#: Property status bits (App::PropertyType): read-only in the editor, and "output"
#: (changing it does not touch the object).
READ_ONLY = 1
OUTPUT = 8


def ensure_properties(obj, table, enumerations=None):
    """Add the properties of ``table`` missing on ``obj`` (at creation, and on documents
    saved by older versions). Rows: (type, name, group, tooltip, default, status bits);
    ``enumerations`` maps enumeration property names to their choices."""
    enumerations = enumerations or {}
    for ptype, name, group, tip, default, attr in table:
        if name in obj.PropertiesList:
            continue
        obj.addProperty(ptype, name, group, tip, attr)
        if name in enumerations:
            setattr(obj, name, enumerations[name])
        elif default is not None:
            setattr(obj, name, default)


def solver_module(error_cls):
    """The compiled ``parafab`` module; ``error_cls`` (the feature's error) if it is missing."""
    try:
        import parafab
    except ImportError as exc:
        raise error_cls("The ParaFab solver module 'parafab' cannot be imported (%s); "
                        "is the workbench installed?" % exc)
    return parafab


def linked_edge(obj, error_cls):
    """``(owner, edge)`` for the ``Edge`` link of ``obj``, the edge in global coordinates;
    ``error_cls`` names what is wrong (no link, missing element, not an edge)."""
    link = obj.Edge
    if not link or link[0] is None or not link[1]:
        raise error_cls("No edge linked: set the 'Edge' property")
    owner, subs = link
    sub = subs[0]
    try:
        edge = owner.Shape.getElement(sub)
    except Exception as exc:  # OCC / FreeCAD raise various types here
        raise error_cls("Cannot get %s of %s: %s" % (sub, owner.Label, exc))
    if edge.ShapeType != "Edge":
        raise error_cls("%s of %s is not an edge" % (sub, owner.Label))
    # owner.Shape is expressed in the owner's container (e.g. a PartDesign Body); move the
    # edge to global coordinates.
    container = owner.getGlobalPlacement().multiply(owner.Placement.inverse())
    if not container.isIdentity():
        edge = edge.copy()
        edge.Placement = container.multiply(edge.Placement)
    return owner, edge


class FeatureProxy(object):
    """Base proxy: subclasses set TYPE, VERSION, PROPERTIES (and ENUMERATIONS)."""

    TYPE = ""
    VERSION = 1
    PROPERTIES = ()
    ENUMERATIONS = None

    def __init__(self, obj):
        self.Type = self.TYPE
        self.Version = self.VERSION
        ensure_properties(obj, self.PROPERTIES, self.ENUMERATIONS)
        obj.Proxy = self

    def onDocumentRestored(self, obj):
        """Upgrade documents saved by older versions (add new properties)."""
        ensure_properties(obj, self.PROPERTIES, self.ENUMERATIONS)
        self.Type = self.TYPE
        self.Version = self.VERSION

    def __getstate__(self):
        """JSON-friendly proxy state."""
        return {"Type": self.TYPE, "Version": self.VERSION}

    def __setstate__(self, state):
        """Restore the state saved by :meth:`__getstate__`."""
        state = state or {}
        self.Type = state.get("Type", self.TYPE)
        self.Version = state.get("Version", self.VERSION)

    # FreeCAD >= 0.21 names.
    def dumps(self):
        return self.__getstate__()

    def loads(self, state):
        return self.__setstate__(state)


class IconViewProvider(object):
    """Base view provider (GUI only): the tree icon ``ICON`` from resources/icons, and no
    state of its own to save. Subclasses keep their class names, which saved documents name."""

    ICON = ""

    def __init__(self, vobj):
        vobj.Proxy = self

    def attach(self, vobj):
        """Called when the view provider is created or restored."""
        self.Object = vobj.Object

    def getIcon(self):
        """Tree icon."""
        from . import icon_path
        return icon_path(self.ICON)

    def __getstate__(self):
        """Nothing to store."""
        return None

    def __setstate__(self, state):
        """Nothing to restore."""
        return None

    dumps = __getstate__
    loads = __setstate__
