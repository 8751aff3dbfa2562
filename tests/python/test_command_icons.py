"""Every command registered in parafab_wb/commands.py has its own toolbar icon: the file
exists in resources/icons, is a well-formed SVG, and no two commands (nor the workbench icon)
share the same file content (SHA-256). Reads commands.py with ``ast``: no FreeCAD needed."""

import ast
import hashlib
import os
import unittest
import xml.etree.ElementTree as ET

REPO = os.path.normpath(os.path.join(os.path.dirname(os.path.abspath(__file__)), os.pardir, os.pardir))
COMMANDS = os.path.join(REPO, "workbench", "freecad", "ParaFab", "parafab_wb", "commands.py")
ICONS = os.path.join(REPO, "resources", "icons")


def command_icons():
    """{command name: icon file name} from the addCommand calls and the icon_path calls or ICON
    attributes of the command classes (inherited ones followed through the base classes)."""
    tree = ast.parse(open(COMMANDS).read())
    class_icon, bases = {}, {}
    for node in tree.body:
        if isinstance(node, ast.ClassDef):
            bases[node.name] = [b.id for b in node.bases if isinstance(b, ast.Name)]
            for sub in ast.walk(node):
                if (isinstance(sub, ast.Call) and isinstance(sub.func, ast.Name)
                        and sub.func.id == "icon_path" and sub.args
                        and isinstance(sub.args[0], ast.Constant)):
                    class_icon[node.name] = sub.args[0].value
            for stmt in node.body:  # a class attribute ICON = "..." (the plot commands)
                if (isinstance(stmt, ast.Assign) and any(isinstance(t, ast.Name) and t.id == "ICON" for t in stmt.targets)
                        and isinstance(stmt.value, ast.Constant) and isinstance(stmt.value.value, str)):
                    class_icon[node.name] = stmt.value.value

    def icon_of(cls):
        if cls in class_icon:
            return class_icon[cls]
        for b in bases.get(cls, []):
            found = icon_of(b)
            if found:
                return found
        return None

    out = {}
    for node in ast.walk(tree):
        if (isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute)
                and node.func.attr == "addCommand"):
            name = node.args[0].value
            inst = node.args[1]
            cls = inst.func.id if isinstance(inst, ast.Call) and isinstance(inst.func, ast.Name) else None
            out[name] = icon_of(cls)
    return out


class CommandIconsTest(unittest.TestCase):
    def test_every_command_has_an_existing_distinct_icon(self):
        icons = command_icons()
        self.assertGreaterEqual(len(icons), 7, icons)  # the commands of this workbench
        digests = {}
        for command, icon in sorted(icons.items()):
            self.assertIsNotNone(icon, "%s has no icon_path(...) pixmap" % command)
            path = os.path.join(ICONS, icon)
            self.assertTrue(os.path.isfile(path), "%s: icon %s does not exist" % (command, path))
            root = ET.parse(path).getroot()
            self.assertTrue(root.tag.endswith("svg"), "%s is not an SVG" % path)
            self.assertGreaterEqual(len(list(root)), 2, "%s draws almost nothing" % path)
            digest = hashlib.sha256(open(path, "rb").read()).hexdigest()
            self.assertNotIn(digest, digests,
                             "%s and %s show the same icon (%s)" % (command, digests.get(digest), icon))
            digests[digest] = command
        workbench = hashlib.sha256(open(os.path.join(ICONS, "ParaFab_Workbench.svg"), "rb").read()).hexdigest()
        self.assertNotIn(workbench, digests, "a command reuses the workbench icon")
        # The file names differ too (two names for one drawing would pass the hash check only
        # if the files were edited apart; keep one file per command).
        self.assertEqual(len(set(icons.values())), len(icons), icons)


if __name__ == "__main__":
    unittest.main()
