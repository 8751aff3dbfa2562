"""The import graph of the workbench package parafab_wb (read with ``ast``: no FreeCAD needed).

* No import cycle among the package's modules, counting the imports inside functions too (a
  lazy import is still an edge: modules that import each other cannot be understood apart).
* The layers (as FreeCAD FEM keeps them apart): document-object modules (those defining a
  ``FeatureProxy``) import neither Qt nor FreeCADGui at module level, nor does anything they
  import at module level (FreeCAD imports them to restore documents, also headless); run objects
  (QProcess) use QtCore only; only the task panels and the commands build Qt widgets.

Prints the graph with ``-v``.
"""

import ast
import os
import unittest

REPO = os.path.normpath(os.path.join(os.path.dirname(os.path.abspath(__file__)), os.pardir, os.pardir))
PACKAGE = os.path.join(REPO, "workbench", "freecad", "ParaFab", "parafab_wb")
NAME = "parafab_wb"


def modules():
    return sorted(f[:-3] for f in os.listdir(PACKAGE) if f.endswith(".py") and f != "__init__.py")


def _imports(tree, known, top_level_only):
    """``(package modules, other modules)`` imported in ``tree``."""
    nodes = tree.body if top_level_only else list(ast.walk(tree))
    inner, outer = set(), set()
    for node in nodes:
        if isinstance(node, ast.ImportFrom):
            if node.level == 1 or node.module == NAME or (node.module or "").startswith(NAME + "."):
                base = (node.module or "") if node.level == 1 else (node.module or "")[len(NAME) + 1:]
                if base:
                    inner.add(base.split(".")[0])
                else:  # from . import a, b (or the package's own names such as icon_path)
                    inner.update(a.name for a in node.names if a.name in known)
            else:
                outer.add(node.module or "")
                outer.update("%s.%s" % (node.module, a.name) for a in node.names)
        elif isinstance(node, ast.Import):
            for a in node.names:
                if a.name.startswith(NAME + "."):
                    inner.add(a.name.split(".")[1])
                else:
                    outer.add(a.name)
    return inner, outer


def graph(top_level_only=False):
    """{module: set of package modules it imports}, and {module: other modules it imports}."""
    known = set(modules())
    edges, external = {}, {}
    for m in known:
        with open(os.path.join(PACKAGE, m + ".py")) as f:
            tree = ast.parse(f.read(), m)
        edges[m], external[m] = _imports(tree, known, top_level_only)
    return edges, external


def cycles(edges):
    """Every elementary cycle found by a depth-first search (each as a list of modules)."""
    found, state, stack = [], {}, []

    def visit(m):
        state[m] = 1
        stack.append(m)
        for n in sorted(edges.get(m, ())):
            if state.get(n) == 1:
                found.append(stack[stack.index(n):] + [n])
            elif n not in state:
                visit(n)
        stack.pop()
        state[m] = 2

    for m in sorted(edges):
        if m not in state:
            visit(m)
    return found


def feature_modules():
    """Modules defining a FeaturePython proxy (a subclass of feature_proxy.FeatureProxy)."""
    out = []
    for m in modules():
        with open(os.path.join(PACKAGE, m + ".py")) as f:
            tree = ast.parse(f.read(), m)
        for node in tree.body:
            if isinstance(node, ast.ClassDef) and any(
                    isinstance(b, ast.Attribute) and b.attr == "FeatureProxy" for b in node.bases):
                out.append(m)
                break
    return out


def _gui(names):
    return sorted(n for n in names if n.startswith("FreeCADGui") or n.startswith("PySide") or n == "pivy")


class ImportGraphTest(unittest.TestCase):
    def test_no_import_cycle(self):
        edges, _ = graph()
        for m in sorted(edges):
            print("%-20s -> %s" % (m, ", ".join(sorted(edges[m])) or "-"))
        self.assertEqual(cycles(edges), [])

    def test_the_cycle_finder_finds_cycles(self):
        self.assertEqual(cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}}), [["a", "b", "c", "a"]])
        self.assertEqual(cycles({"a": {"b"}, "b": set(), "c": {"a", "b"}}), [])

    def test_document_objects_load_without_qt(self):
        features = feature_modules()
        self.assertGreaterEqual(len(features), 4, features)  # strip, rod, revolution, analysis
        edges, external = graph(top_level_only=True)
        for m in features:
            seen, todo = set(), [m]
            while todo:  # everything imported at module level, transitively
                n = todo.pop()
                if n not in seen:
                    seen.add(n)
                    todo.extend(edges.get(n, ()))
            for n in sorted(seen):
                self.assertEqual(_gui(external[n]), [], "%s (imported by %s at module level)" % (n, m))

    def test_layers_import_downwards(self):
        """Document objects <- run objects <- task panels: a document-object module imports no
        run object or panel (its view provider, GUI only, may open its panel), a run object no
        panel or view provider."""
        edges, _ = graph()
        runs = {"cli_runner", "optimize_runner"}
        panels = {m for m in edges if m.endswith("_panel")}
        views = {m for m in edges if m.endswith("_view")}
        self.assertTrue(panels >= {"analysis_panel", "optimize_panel", "task_panel"}, panels)
        for m in sorted(set(feature_modules()) | {"analysis_job", "optimize_feature", "outcome"}):
            self.assertEqual(sorted(edges[m] & (runs | panels)), [], m)
        for m in sorted(runs):
            self.assertEqual(sorted(edges[m] & (panels | views)), [], m)

    def test_only_panels_and_commands_build_widgets(self):
        _, external = graph()
        for m, names in sorted(external.items()):
            widgets = sorted(n for n in names if n in ("PySide.QtGui", "PySide.QtWidgets"))
            if widgets:
                self.assertTrue(m.endswith("_panel") or m in ("commands", "task_panel"), (m, widgets))


if __name__ == "__main__":
    unittest.main()
