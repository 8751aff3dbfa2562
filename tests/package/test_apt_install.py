"""The .deb installed on this machine with apt, as a user would (issue 53, "Done when"), then
removed: ``apt-get install ./parafab_<version>_amd64.deb`` resolves its Depends from what is
installed, then an unprivileged user (``nobody``, a fresh HOME) runs ``/usr/bin/parafab``,
``/usr/bin/python3 -c "import parafab"`` and FreeCADCmd, which loads the workbench from FreeCAD's
system Mod folder by itself (no ``-P``) and creates a strip feature; ``apt-get purge`` then
leaves none of the package's files. Root only (CI runs as root); ctest runs it alone (RUN_SERIAL)
so that no other test sees the system-wide workbench while it is installed.

Environment: PARAFAB_BUILD_DIR (configured, parafab_cli and parafab_python built), PARAFAB_CLI.
"""

import glob
import json
import os
import shutil
import tempfile
import sys
import unittest

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from test_package import run  # noqa: E402  (run a command, failing with its output)

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.normpath(os.path.join(HERE, os.pardir, os.pardir))
BUILD = os.path.abspath(os.environ.get("PARAFAB_BUILD_DIR", os.path.join(REPO, "build")))
BUILD_CLI = os.environ.get("PARAFAB_CLI", os.path.join(BUILD, "workbench", "entry", "parafab"))
STRIP_SAMPLE = os.path.join(REPO, "samples", "strips", "elliptic_arc.json")
WB = "/usr/share/freecad/Mod/ParaFab"


def installed():
    p = run(["dpkg-query", "-W", "-f=${Status}", "parafab"], check=False)
    return p.returncode == 0 and "install ok installed" in p.stdout


def as_user(cmd, home, **env):
    """``cmd`` as the unprivileged user nobody, with only a plain environment."""
    plain = {"HOME": home, "PATH": "/usr/bin:/bin", "LANG": "C.UTF-8", "PYTHONDONTWRITEBYTECODE": "1"}
    plain.update(env)
    return run(["runuser", "-u", "nobody", "--", "env", "-i"] + ["%s=%s" % kv for kv in plain.items()] + cmd,
               cwd=home, timeout=300)


@unittest.skipUnless(os.geteuid() == 0 and shutil.which("apt-get") and shutil.which("runuser"),
                     "installs a package system-wide: root with apt-get and runuser only")
class AptInstall(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.tmp = tempfile.mkdtemp(prefix="parafab_apt_")
        os.chmod(cls.tmp, 0o755)
        if installed():  # a package left by an interrupted run of this test
            run(["apt-get", "purge", "-y", "parafab"], env=dict(os.environ, DEBIAN_FRONTEND="noninteractive"))
        out = os.path.join(cls.tmp, "cpack")
        run(["cpack", "-G", "DEB", "--config", os.path.join(BUILD, "CPackConfig.cmake"), "-B", out], cwd=cls.tmp, timeout=300)
        cls.deb = sorted(glob.glob(os.path.join(out, "parafab_*.deb")))[-1]
        cls.files = [line.split(None, 5)[5].split(" -> ")[0][1:]
                     for line in run(["dpkg-deb", "-c", cls.deb]).stdout.splitlines() if not line.startswith("d")]
        cls.install = run(["apt-get", "install", "-y", "--no-install-recommends", cls.deb],
                          env=dict(os.environ, DEBIAN_FRONTEND="noninteractive"), check=False, timeout=300)
        cls.reference = json.loads(run([BUILD_CLI, "strip", STRIP_SAMPLE]).stdout)

    @classmethod
    def tearDownClass(cls):
        try:
            run(["apt-get", "purge", "-y", "parafab"], env=dict(os.environ, DEBIAN_FRONTEND="noninteractive"),
                check=False)
        finally:
            shutil.rmtree(cls.tmp, ignore_errors=True)

    def home(self):
        h = tempfile.mkdtemp(dir=self.tmp)
        shutil.chown(h, "nobody")
        return h

    def test_1_apt_installs_the_deb(self):
        self.assertEqual(self.install.returncode, 0, self.install.stdout[-2000:] + self.install.stderr[-2000:])
        self.assertTrue(installed())
        for f in self.files:
            self.assertTrue(os.path.lexists(f), f)

    def test_2_any_user_runs_the_cli_and_the_module(self):
        self.assertTrue(installed(), "apt did not install the package")
        home = self.home()
        version = json.loads(as_user(["parafab", "version"], home).stdout)
        self.assertEqual(version["scripts"], "/usr/share/parafab/scripts")
        strip = json.loads(as_user(["parafab", "strip", STRIP_SAMPLE], home).stdout)
        self.assertAlmostEqual(strip["R"], self.reference["R"], delta=1e-12 * self.reference["R"])
        p = as_user(["/usr/bin/python3", "-c", "import json, parafab; print(json.dumps([parafab.__file__, "
                     "parafab.__version__, parafab.design_strip(json.load(open(%r)))['R']]))" % STRIP_SAMPLE], home)
        path, module_version, R = json.loads(p.stdout)
        self.assertTrue(path.startswith("/usr/lib/python3/dist-packages/parafab"), path)
        self.assertEqual(module_version, version["parafab"])
        self.assertAlmostEqual(R, self.reference["R"], delta=1e-12 * self.reference["R"])

    def test_3_freecad_loads_the_workbench_from_its_system_folder(self):
        self.assertTrue(installed(), "apt did not install the package")
        home = self.home()
        check = os.path.join(home, "freecad_check.py")
        shutil.copy(os.path.join(HERE, "freecad_check.py"), check)
        report = os.path.join(home, "report.json")
        p = as_user(["freecadcmd", check], home, PARAFAB_WB_DIR=WB, PARAFAB_CHECK_OUT=report)
        self.assertTrue(os.path.isfile(report), "freecadcmd wrote no report:\n%s\n%s" % (p.stdout, p.stderr))
        with open(report) as f:
            rep = json.load(f)
        self.assertNotIn("error", rep, rep.get("error"))
        self.assertTrue(rep["module"].startswith("/usr/lib/python3/dist-packages/parafab"), rep["module"])
        self.assertEqual(rep["workbench"], os.path.join(WB, "parafab_wb", "__init__.py"))
        self.assertEqual(rep["cli_real"], "/usr/bin/parafab")
        self.assertEqual(rep["strip"]["state"], ["Up-to-date"])
        self.assertAlmostEqual(rep["strip"]["R"], 1.0, delta=1e-9)

    def test_4_purge_removes_every_file(self):
        self.assertTrue(installed(), "apt did not install the package")
        run(["apt-get", "purge", "-y", "parafab"], env=dict(os.environ, DEBIAN_FRONTEND="noninteractive"))
        self.assertFalse(installed())
        self.assertEqual([f for f in self.files if os.path.lexists(f)], [])


if __name__ == "__main__":
    unittest.main()
