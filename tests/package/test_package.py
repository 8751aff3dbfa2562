"""Packaging (issue 53): ParaFab installed, run from where it was installed.

Two fresh roots, nothing installed on this machine:

* ``install``: ``DESTDIR=<tmp>/install cmake --install BUILD --prefix /usr``;
* ``deb``: the package CPack builds (``cpack -G DEB``), unpacked with ``dpkg-deb -x``.

In each root: the CLI (``parafab version``, a strip job matching the build tree's CLI), the
module (Debian's /usr/bin/python3 with PYTHONPATH at the root's dist-packages: the installed
file, not the build tree's), FreeCADCmd with the root's workbench folder (``-P``, since
``freecadcmd -M`` segfaults in 0.20.2) creating a strip feature headless and finding the CLI
the task panels run, and the chart scripts found beside the install. The .deb's name, fields
(Depends: dpkg-shlibdeps' libraries, the module's Python, FreeCAD, numpy, matplotlib) and
listing are checked too.

Environment: PARAFAB_BUILD_DIR (configured, parafab_cli and parafab_python built) and
PARAFAB_CLI (the build tree's CLI, the reference the installed one must agree with).
"""

import glob
import json
import os
import re
import shutil
import subprocess
import sys
import tempfile
import unittest

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.normpath(os.path.join(HERE, os.pardir, os.pardir))
BUILD = os.path.abspath(os.environ.get("PARAFAB_BUILD_DIR", os.path.join(REPO, "build")))
BUILD_CLI = os.environ.get("PARAFAB_CLI", os.path.join(BUILD, "workbench", "entry", "parafab"))
PYTHON = "/usr/bin/python3"
STRIP_SAMPLE = os.path.join(REPO, "samples", "strips", "elliptic_arc.json")
BRACKET = os.path.join(REPO, "samples", "parts", "l_bracket.step")

# The install layout under the prefix /usr (CMakeLists.txt, "Install layout").
BIN = "usr/bin/parafab"
PYDIR = "usr/lib/python3/dist-packages"
WB = "usr/share/freecad/Mod/ParaFab"
SCRIPTS = "usr/share/parafab/scripts"


def run(cmd, env=None, cwd=None, timeout=120, check=True):
    """Run ``cmd``; on a non-zero exit fail with its output."""
    p = subprocess.run(cmd, env=env, cwd=cwd, capture_output=True, text=True, timeout=timeout)
    if check and p.returncode != 0:
        raise AssertionError("%s exited with %d\nstdout:\n%s\nstderr:\n%s"
                             % (" ".join(cmd), p.returncode, p.stdout[-3000:], p.stderr[-3000:]))
    return p


def clean_env(**extra):
    """The environment without ParaFab's overrides (PARAFAB_CLI etc.): the installed files must
    find each other by themselves."""
    env = {k: v for k, v in os.environ.items() if not k.startswith("PARAFAB_") and k != "PYTHONPATH"}
    env.update(PYTHONDONTWRITEBYTECODE="1", PYTHONNOUSERSITE="1")
    env.update(extra)
    return env


def cache_value(name):
    with open(os.path.join(BUILD, "CMakeCache.txt")) as f:
        for line in f:
            if line.startswith(name + ":"):
                return line.split("=", 1)[1].strip()
    raise AssertionError("%s not in %s/CMakeCache.txt" % (name, BUILD))


def files_under(root):
    """Relative paths of the files and links under ``root``."""
    out = set()
    for d, dirs, files in os.walk(root):
        for name in files + [x for x in dirs if os.path.islink(os.path.join(d, x))]:
            out.add(os.path.relpath(os.path.join(d, name), root))
    return out


class Package(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.tmp = tempfile.mkdtemp(prefix="parafab_package_")
        cls.version = cache_value("CMAKE_PROJECT_VERSION")
        cls.module_name = os.path.basename(glob.glob(os.path.join(BUILD, "workbench", "entry", "parafab*.so"))[0])
        cls.roots = {"install": os.path.join(cls.tmp, "install"), "deb": os.path.join(cls.tmp, "deb")}
        run(["cmake", "--install", BUILD, "--prefix", "/usr"],
            env=dict(os.environ, DESTDIR=cls.roots["install"]))
        out = os.path.join(cls.tmp, "cpack")
        run(["cpack", "-G", "DEB", "--config", os.path.join(BUILD, "CPackConfig.cmake"), "-B", out],
            cwd=cls.tmp, timeout=300)
        cls.debs = sorted(glob.glob(os.path.join(out, "*.deb")))
        cls.deb = os.path.join(out, "parafab_%s_amd64.deb" % cls.version)
        run(["dpkg-deb", "-x", cls.deb, cls.roots["deb"]])
        cls.fields = {}
        for line in run(["dpkg-deb", "-f", cls.deb]).stdout.splitlines():
            if line[:1].strip():
                key, _, value = line.partition(":")
                cls.fields[key] = value.strip()
        cls.listing = {}
        for line in run(["dpkg-deb", "-c", cls.deb]).stdout.splitlines():
            # mode owner size date time ./path [-> target]
            parts = line.split(None, 5)
            path, _, target = parts[5].partition(" -> ")
            cls.listing[os.path.normpath(path)] = target
        cls.reference = json.loads(run([BUILD_CLI, "strip", STRIP_SAMPLE]).stdout)

    @classmethod
    def tearDownClass(cls):
        shutil.rmtree(cls.tmp, ignore_errors=True)

    # ----------------------------------------------------------------------------- the .deb
    def test_deb_is_named_by_version_and_architecture(self):
        self.assertEqual(self.debs, [self.deb])
        self.assertEqual(self.fields["Package"], "parafab")
        self.assertEqual(self.fields["Version"], self.version)
        self.assertEqual(self.fields["Architecture"], run(["dpkg", "--print-architecture"]).stdout.strip())

    def test_deb_depends_on_what_it_runs(self):
        depends = [d.strip() for d in self.fields["Depends"].split(",")]
        names = {re.split(r"[\s(|]", d)[0] for d in depends}
        for package in ("freecad", "python3-numpy", "python3-matplotlib", "libc6", "libstdc++6"):
            self.assertIn(package, names, self.fields["Depends"])
        # The module's ABI: the Python it was built for, this minor version only.
        major, minor = sys.version_info[:2] if sys.executable == PYTHON else map(int, run(
            [PYTHON, "-c", "import sys; print(*sys.version_info[:2])"]).stdout.split())
        self.assertIn("python3 (>= %d.%d)" % (major, minor), depends)
        self.assertIn("python3 (<< %d.%d)" % (major, minor + 1), depends)
        # dpkg-shlibdeps: every library the CLI and the module link is a dependency (by the
        # package that ships it, or the alternative's soname, as for libblas.so.3).
        for binary in (BIN, os.path.join(PYDIR, self.module_name)):
            path = os.path.join(self.roots["deb"], binary)
            needed = re.findall(r"\(NEEDED\)\s+Shared library: \[([^\]]+)\]", run(["readelf", "-d", path]).stdout)
            self.assertGreater(len(needed), 5, binary)
            resolved = dict(re.findall(r"^\s*(\S+) => (\S+)", run(["ldd", path]).stdout, re.M))
            for soname in needed:
                if soname.startswith("ld-linux"):
                    continue
                self.assertIn(soname, resolved, "%s: %s not found by ldd" % (binary, soname))
                owner = None
                for candidate in (resolved[soname], os.path.realpath(resolved[soname])):
                    for p in (candidate, re.sub(r"^/usr/lib/", "/lib/", candidate),
                              re.sub(r"^/lib/", "/usr/lib/", candidate)):
                        q = run(["dpkg-query", "-S", p], check=False)
                        if q.returncode == 0:
                            owner = q.stdout.split(":")[0].strip()
                            break
                    if owner:
                        break
                self.assertTrue(owner in names or soname in self.fields["Depends"],
                                "%s needs %s (%s) but Depends is %s" % (binary, soname, owner, self.fields["Depends"]))

    def test_deb_lists_cli_module_workbench_and_scripts(self):
        listed = self.listing
        for path in (BIN, os.path.join(PYDIR, self.module_name),
                     WB + "/Init.py", WB + "/InitGui.py", WB + "/package.xml", WB + "/LICENSE",
                     WB + "/parafab_wb/__init__.py", WB + "/parafab_wb/strip_feature.py",
                     WB + "/parafab_wb/cli_runner.py", WB + "/Resources/icons/ParaFab_Workbench.svg",
                     WB + "/Resources/icons/ParaFab_Strip.svg", SCRIPTS + "/plot_optimization.py",
                     "usr/share/doc/parafab/copyright"):
            self.assertIn(os.path.normpath("./" + path), listed)
        # The CLI the task panels run is a relative link to bin/parafab.
        self.assertEqual(listed[os.path.normpath("./" + WB + "/parafab")], "../../../../bin/parafab")
        self.assertFalse([p for p in listed if "__pycache__" in p or p.endswith(".pyc")])
        # Every workbench source and icon is there.
        wb_src = os.path.join(REPO, "workbench", "freecad", "ParaFab")
        for d, _, files in os.walk(wb_src):
            for name in files:
                if name.endswith(".pyc"):
                    continue
                rel = os.path.relpath(os.path.join(d, name), wb_src)
                self.assertIn(os.path.normpath("./%s/%s" % (WB, rel)), listed)
        for name in os.listdir(os.path.join(REPO, "resources", "icons")):
            self.assertIn(os.path.normpath("./%s/Resources/icons/%s" % (WB, name)), listed)

    def test_deb_and_cmake_install_hold_the_same_files(self):
        self.assertEqual(files_under(self.roots["deb"]) - {"usr/share/doc/parafab/changelog.gz"},
                         files_under(self.roots["install"]))

    def test_package_xml_and_copyright(self):
        with open(os.path.join(REPO, "LICENSE")) as f:
            licence = f.read()
        self.assertIn("SPDX: LGPL-2.1-or-later", licence)
        for root in self.roots.values():
            with open(os.path.join(root, "usr/share/doc/parafab/copyright")) as f:
                self.assertEqual(f.read(), licence)
            with open(os.path.join(root, WB, "package.xml")) as f:
                xml = f.read()
            self.assertIn("<version>%s</version>" % self.version, xml)
            self.assertIn('<license file="LICENSE">LGPL-2.1-or-later</license>', xml)

    # ----------------------------------------------------------------------------- the CLI
    def test_cli_version_and_scripts_folder(self):
        for name, root in self.roots.items():
            with self.subTest(root=name):
                v = json.loads(run([os.path.join(root, BIN), "version"], env=clean_env(), cwd=self.tmp).stdout)
                self.assertEqual(v["parafab"], self.version)
                self.assertRegex(v["opencascade"], r"^7\.6\.")
                self.assertEqual(v["scripts"], os.path.join(root, SCRIPTS))
                self.assertTrue(os.path.isfile(os.path.join(v["scripts"], "plot_optimization.py")))
                # Through the workbench's link the CLI still finds the root's scripts.
                v = json.loads(run([os.path.join(root, WB, "parafab"), "version"], env=clean_env()).stdout)
                self.assertEqual(v["scripts"], os.path.join(root, SCRIPTS))

    def test_cli_strip_job_agrees_with_the_build_tree(self):
        ref = self.reference
        self.assertTrue(ref["feasible"])
        for name, root in self.roots.items():
            with self.subTest(root=name):
                r = json.loads(run([os.path.join(root, BIN), "strip", STRIP_SAMPLE], env=clean_env()).stdout)
                self.assertTrue(r["feasible"])
                self.assertEqual(sorted(r), sorted(ref))
                self.assertAlmostEqual(r["R"], ref["R"], delta=1e-12 * ref["R"])
                self.assertEqual(len(r["width"]), len(ref["width"]))
                for a, b in zip(r["width"], ref["width"]):
                    self.assertAlmostEqual(a, b, delta=1e-12 * abs(b))

    def test_cli_optimize_draws_its_chart_with_the_installed_script(self):
        # One iterate of a volume objective on the L-bracket's hole radius (a few seconds); the
        # source tree's scripts are hidden, so only the installed copy can draw the chart.
        job = {"material": {"E": 210000, "nu": 0.3}, "element": "hex8", "grid": {"cells": 4},
               "supports": [{"point": [0, 20, 30]}], "loads": [{"point": [60, 20, 4], "force": [0, 0, -500]}],
               "objective": {"type": "volume"}, "parameters": [{"point": [44, 12, 4], "parameter": "radius"}],
               "max_iterations": 1}
        root = self.roots["deb"]
        work = tempfile.mkdtemp(dir=self.tmp)
        with open(os.path.join(work, "job.json"), "w") as f:
            json.dump(job, f)
        part = os.path.join(work, "l_bracket.step")
        shutil.copy(BRACKET, part)
        hidden = os.path.join(REPO, "workbench", "scripts", "plot_optimization.py")
        self.assertTrue(os.path.isfile(hidden))
        out = os.path.join(work, "out")
        h = json.loads(run([os.path.join(root, BIN), "optimize", part, os.path.join(work, "job.json"), "-o", out],
                           env=clean_env(PARAFAB_SCRIPTS_DIR=""), timeout=120).stdout)
        self.assertEqual(h["chart"], os.path.join(out, "history.png"))
        with open(h["chart"], "rb") as f:
            self.assertEqual(f.read(8), b"\x89PNG\r\n\x1a\n")
        self.assertTrue(os.path.isfile(os.path.join(out, "optimized.step")))

    # ----------------------------------------------------------------------------- the module
    def test_module_is_the_installed_file(self):
        script = ("import json, os, sys, parafab\n"
                  "spec = json.load(open(sys.argv[1]))\n"
                  "r = parafab.design_strip(spec)\n"
                  "print(json.dumps({'file': os.path.realpath(parafab.__file__), 'version': parafab.__version__,"
                  " 'scripts': parafab.scripts_dir(), 'feasible': r['feasible'], 'R': r['R']}))\n")
        for name, root in self.roots.items():
            with self.subTest(root=name):
                pydir = os.path.join(root, PYDIR)
                m = json.loads(run([PYTHON, "-c", script, STRIP_SAMPLE], cwd=self.tmp,
                                   env=clean_env(PYTHONPATH=pydir)).stdout)
                self.assertEqual(m["file"], os.path.join(pydir, self.module_name))
                self.assertFalse(m["file"].startswith(BUILD + os.sep))
                self.assertEqual(m["version"], self.version)
                self.assertEqual(m["scripts"], os.path.join(root, SCRIPTS))
                self.assertTrue(m["feasible"])
                self.assertAlmostEqual(m["R"], self.reference["R"], delta=1e-12 * self.reference["R"])

    # ----------------------------------------------------------------------------- FreeCAD
    def test_freecad_runs_the_installed_workbench(self):
        with open(os.path.join(REPO, "workbench", "freecad", "ParaFab", "InitGui.py")) as f:
            classname = re.search(r"^class (\w+)\(FreeCADGui\.Workbench\)", f.read(), re.M).group(1)
        for name, root in self.roots.items():
            with self.subTest(root=name):
                wb = os.path.join(root, WB)
                home = tempfile.mkdtemp(dir=self.tmp)  # no user Mod folder, no settings
                out = os.path.join(home, "report.json")
                p = run(["freecadcmd", "-P", wb, os.path.join(HERE, "freecad_check.py")], cwd=home, timeout=120,
                        env=clean_env(HOME=home, PYTHONPATH=os.path.join(root, PYDIR),
                                      PARAFAB_WB_DIR=wb, PARAFAB_CHECK_OUT=out))
                self.assertTrue(os.path.isfile(out), "freecadcmd wrote no report:\n%s\n%s" % (p.stdout, p.stderr))
                with open(out) as f:
                    rep = json.load(f)
                self.assertNotIn("error", rep, rep.get("error"))
                self.assertEqual(rep["module"], os.path.join(root, PYDIR, self.module_name))
                self.assertEqual(rep["workbench"], os.path.join(wb, "parafab_wb", "__init__.py"))
                self.assertEqual(rep["icon"], os.path.join(wb, "Resources", "icons", "ParaFab_Workbench.svg"))
                self.assertEqual(rep["cli"], os.path.join(wb, "parafab"))
                self.assertEqual(rep["cli_real"], os.path.join(root, BIN))
                self.assertEqual(rep["cli_version"]["parafab"], self.version)
                self.assertEqual(rep["cli_version"]["scripts"], os.path.join(root, SCRIPTS))
                meta = rep["metadata"]
                self.assertEqual((meta["name"], meta["version"], meta["supported"]), ("ParaFab", self.version, True))
                self.assertEqual([x["name"] for x in meta["license"]], ["LGPL-2.1-or-later"])
                self.assertTrue(os.path.isfile(os.path.join(wb, meta["icon"])))
                self.assertEqual(len(meta["workbenches"]), 1)
                w = meta["workbenches"][0]
                self.assertEqual((w["classname"], w["supported"]), (classname, True))
                self.assertTrue(os.path.isfile(os.path.join(w["dir"], "InitGui.py")))
                self.assertTrue(os.path.isfile(os.path.join(w["dir"], w["icon"])))
                s = rep["strip"]
                self.assertEqual(s["state"], ["Up-to-date"])
                self.assertTrue(s["feasible"], s["reason"])
                self.assertTrue(s["valid"])
                self.assertEqual(s["solids"], 2)
                self.assertAlmostEqual(s["R"], 1.0, delta=1e-9)  # constant curvature
                self.assertAlmostEqual(s["length_mm"], 300.0, delta=1e-6 * 300)  # 150 mm x 2 rad
                self.assertAlmostEqual(s["bent_width_mm"], 10.0, delta=1e-6)  # the minimum width


if __name__ == "__main__":
    unittest.main()
