"""The Addon Manager's install, headless: a clone of this repository in a clean FreeCAD user
Mod folder, first started by ``freecadcmd`` with no virtual environment.

Each FreeCAD here is a separate ``freecadcmd`` process with a throw-away user folder
(``FREECAD_USER_HOME``, and ``FREECAD_USER_DATA`` for FreeCAD versions that read it; the
Mod folder is asked from FreeCAD itself, ``getUserAppDataDir()``) and a throw-away
``user.cfg`` (``-u``).  The first start must name the install (the start-up line), a
script's ``deps.install()`` builds the venv with pip as configured on this machine, and
the same FreeCAD then fabricates the bundled HMD example; a second start needs nothing.
Without a package index (``PIP_NO_INDEX=1``, ``PIP_FIND_LINKS`` a folder that does not
exist) the install ends in one message with the command to run by hand.  The venv is
built once for the class.  Scripts report in a JSON file (FreeCAD 1.0's freecadcmd
buffers its stdout on a pipe).
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import tempfile
import unittest
from pathlib import Path

import FreeCAD as App

ROOT = Path(__file__).resolve().parents[2]

#: Seconds an install may take (pip downloads about 1 GB where nothing is cached).
INSTALL_TIMEOUT_S = 1500

#: What the start-up line of a FreeCAD without the packages says.
OFFER = "its Python packages are not installed"


def freecadcmd() -> str:
    """The freecadcmd of the FreeCAD running these tests."""
    beside = Path(App.getHomePath()) / "bin" / ("FreeCADCmd.exe" if os.name == "nt" else "freecadcmd")
    return str(beside) if beside.is_file() else (shutil.which("freecadcmd") or shutil.which("FreeCADCmd"))


class UserFolder:
    """A throw-away FreeCAD user folder with this repository cloned into its Mod folder."""

    def __init__(self, base: Path, name: str):
        self.home = base / name
        self.home.mkdir(parents=True)
        self.cfg = self.home / "user.cfg"
        # FreeCAD 0.20 runs $VIRTUAL_ENV/bin/activate_this.py at start-up when VIRTUAL_ENV is set
        # (a shell with a venv activated), which venv-made folders lack: a fresh user has none
        self.env = {key: value for key, value in os.environ.items()
                    if key not in ("FABRICKATOR_VENV", "PYTHONPATH", "VIRTUAL_ENV")}
        self.env.update(FREECAD_USER_HOME=str(self.home), FREECAD_USER_DATA=str(self.home),
                        FABRICKATOR_SLICER="none", PYTHONUNBUFFERED="1")
        self.data = Path(self.ask("FreeCAD.getUserAppDataDir()"))
        if self.home.resolve() not in (self.data.resolve(), *self.data.resolve().parents):
            # a failure, not a skip: the Addon Manager's install would go untested
            raise AssertionError(f"this FreeCAD keeps its user data in {self.data} whatever "
                                 f"FREECAD_USER_HOME / FREECAD_USER_DATA say: not cloning into it")
        self.mod = self.data / "Mod" / "Fabrickator"
        self.mod.parent.mkdir(parents=True, exist_ok=True)
        subprocess.run(["git", "clone", "-q", str(ROOT), str(self.mod)], check=True, timeout=120)

    def write_config(self, start_workbench: str) -> None:
        """A fresh ``user.cfg`` whose start workbench is ``start_workbench``."""
        self.cfg.write_text('<?xml version="1.0" encoding="UTF-8" standalone="no" ?>\n<FCParameters>'
                            '<FCParamGroup Name="Root"><FCParamGroup Name="BaseApp"><FCParamGroup '
                            'Name="Preferences"><FCParamGroup Name="General"><FCText Name="AutoloadModule">'
                            f'{start_workbench}</FCText></FCParamGroup></FCParamGroup></FCParamGroup>'
                            '</FCParamGroup></FCParameters>\n')

    def ask(self, expression: str) -> str:
        """The value of a Python expression in this user folder's freecadcmd."""
        answer = self.home / "answer.json"
        run = self.run(f"import json, FreeCAD\njson.dump({expression}, open({str(answer)!r}, 'w'))\n", timeout=120)
        if not answer.exists():
            raise AssertionError(f"freecadcmd did not answer {expression}: {run.stdout[-2000:]}")
        return json.loads(answer.read_text())

    def run(self, script: str, timeout: float, **env) -> subprocess.CompletedProcess:
        """Run ``script`` (ending the process itself) in freecadcmd with this user folder."""
        path = self.home / "script.py"
        path.write_text(script + "\nimport os\nos._exit(0)\n")
        return subprocess.run([freecadcmd(), "-u", str(self.cfg), str(path)], capture_output=True, text=True,
                              env={**self.env, **env}, timeout=timeout, cwd=self.home,
                              stdin=subprocess.DEVNULL)


#: The first run: what the Addon Manager user's script does, then the example.
FIRST_RUN = """
import json, sys
out = {"numpy_loaded": "numpy" in sys.modules}
from FabrickatorWorkbench import deps
out["root"] = deps.ROOT
out["needs"] = deps.needs_install()
seen = []
result = deps.install(progress=lambda fraction, line: seen.append((fraction, line)))
out["ok"], out["message"] = result.ok, result.message
out["fractions"] = [f for f, _ in seen if f is not None]
out["last_lines"] = [line for _, line in seen][-3:]
out["needs_after"] = deps.needs_install()
import numpy
out["numpy"] = [numpy.__version__, numpy.__file__]
sys.path.insert(0, deps.ROOT + "/examples")
import hmd
hmd.build_hmd().val().exportStep(REPORT + ".step")
import FabrickatorWorkbench as fab
from FabrickatorWorkbench import example
f = example.open_example(REPORT + ".step")
out["status"], out["bricks"] = f.Status, f.Bricks
out["parts"] = [p.PartId for p in fab.printed_parts(f)]
json.dump(out, open(REPORT, "w"), indent=1)
"""

#: A later start: the packages are there and in use from the start.
LATER_RUN = """
import json, sys
from FabrickatorWorkbench import deps
import numpy, cadquery, core
json.dump({"needs": deps.needs_install(), "check": deps.check("the test"), "numpy": numpy.__file__,
           "core": core.__file__}, open(REPORT, "w"))
"""

#: An install without a package index.
OFFLINE_RUN = """
import json
from FabrickatorWorkbench import deps
result = deps.install()
json.dump({"ok": result.ok, "message": result.message, "needs": deps.needs_install(),
           "fix": deps.fix_command()}, open(REPORT, "w"))
"""


class TestAddonManagerInstall(unittest.TestCase):
    """An Addon Manager clone without .venv: the offer, the install, then the example."""

    @classmethod
    def setUpClass(cls):
        cls.base = Path(tempfile.mkdtemp(prefix="fabrickator-install-"))
        cls.user = UserFolder(cls.base, "user")
        cls.report = cls.user.home / "first.json"
        cls.first = cls.user.run(f"REPORT = {str(cls.report)!r}\n" + FIRST_RUN, timeout=INSTALL_TIMEOUT_S)

    @classmethod
    def tearDownClass(cls):
        shutil.rmtree(cls.base, ignore_errors=True)

    def first_report(self) -> dict:
        out = self.first.stdout + self.first.stderr
        self.assertTrue(self.report.exists(), f"the first run did not finish: {out[-3000:]}")
        return json.loads(self.report.read_text())

    def test_the_clone_is_where_freecad_looks_and_has_no_venv_yet(self):
        report = self.first_report()
        self.assertEqual(Path(report["root"]), self.user.mod)
        self.assertIn(str(self.user.data), report["root"])
        self.assertIn("cannot be imported", report["needs"])

    def test_the_first_start_names_the_install(self):
        out = self.first.stdout + self.first.stderr
        line = next((text for text in out.splitlines() if OFFER in text), None)
        self.assertIsNotNone(line, out[-3000:])
        self.assertIn("deps.install()", line)
        self.assertIn(f"-m venv --clear {self.user.mod / '.venv'}", line)
        self.assertIn(f"-r {self.user.mod / 'requirements.txt'}", line)
        self.assertNotIn("Traceback", out)

    def test_install_builds_the_venv_and_the_same_freecad_fabricates_the_example(self):
        report = self.first_report()
        self.assertFalse(report["numpy_loaded"], "numpy was loaded before the install: a restart would be needed")
        self.assertTrue(report["ok"], report["message"])
        self.assertEqual(report["message"], "Fabrickator's Python packages are installed and in use")
        self.assertIsNone(report["needs_after"])
        self.assertTrue((self.user.mod / ".venv" / ".installed").is_file())
        fractions = report["fractions"]
        self.assertEqual(fractions, sorted(fractions))
        self.assertEqual(fractions[-1], 1.0)
        self.assertGreater(len(set(fractions)), 10)
        self.assertTrue(report["last_lines"][-1].startswith("Successfully installed"), report["last_lines"])
        self.assertGreaterEqual(int(report["numpy"][0].split(".")[0]), 2)
        self.assertTrue(report["numpy"][1].startswith(str(self.user.mod / ".venv")), report["numpy"])
        self.assertTrue(report["status"].startswith("ok"), report["status"])
        self.assertGreater(report["bricks"], 100)
        self.assertEqual(report["parts"], ["P1", "P2"])

    def test_a_later_start_uses_the_venv_and_says_nothing(self):
        self.first_report()
        report = self.user.home / "later.json"
        run = self.user.run(f"REPORT = {str(report)!r}\n" + LATER_RUN, timeout=300)
        out = run.stdout + run.stderr
        self.assertTrue(report.exists(), out[-3000:])
        later = json.loads(report.read_text())
        self.assertIsNone(later["needs"])
        self.assertTrue(later["check"])
        self.assertTrue(later["numpy"].startswith(str(self.user.mod / ".venv")))
        self.assertEqual(Path(later["core"]).parent, self.user.mod / "core")
        self.assertNotIn(OFFER, out)


class TestInstallWithoutNetwork(unittest.TestCase):
    """No package index: one message saying so, with the command to run by hand."""

    def test_no_package_index_is_one_message_with_the_command(self):
        base = Path(tempfile.mkdtemp(prefix="fabrickator-offline-"))
        try:
            user = UserFolder(base, "offline")
            report = user.home / "offline.json"
            run = user.run(f"REPORT = {str(report)!r}\n" + OFFLINE_RUN, timeout=600,
                           PIP_NO_INDEX="1", PIP_FIND_LINKS=str(base / "no-such-folder"))
            out = run.stdout + run.stderr
            self.assertTrue(report.exists(), out[-3000:])
            offline = json.loads(report.read_text())
            self.assertFalse(offline["ok"])
            message = offline["message"]
            self.assertTrue(message.startswith("Fabrickator could not download its Python packages: no network, "
                                               "or the package index cannot be reached (pip: No matching "
                                               "distribution found for "), message)
            self.assertTrue(message.endswith("run in a terminal: " + offline["fix"]), message)
            self.assertIn(str(user.mod / "requirements.txt"), offline["fix"])
            self.assertNotIn("\n", message)
            self.assertIsNotNone(offline["needs"])
            self.assertFalse((user.mod / ".venv" / ".installed").exists())
            self.assertNotIn("Traceback", out)
        finally:
            shutil.rmtree(base, ignore_errors=True)



class TestPackageXml(unittest.TestCase):
    """package.xml as FreeCAD's own reader (App.Metadata, which the Addon Manager uses) sees it."""

    def test_freecad_reads_the_workbench_and_its_optional_python_packages(self):
        import xml.etree.ElementTree as ElementTree

        metadata = App.Metadata(str(ROOT / "package.xml"))
        self.assertEqual(metadata.Name, "Fabrickator")
        self.assertRegex(metadata.Version, r"^\d+\.\d+\.\d+$")
        self.assertTrue((ROOT / metadata.Icon).is_file(), metadata.Icon)
        self.assertEqual(metadata.FreeCADMin, "0.20.0")
        self.assertTrue(metadata.supportsCurrentFreeCAD())
        [workbench] = metadata.Content["workbench"]
        self.assertEqual(workbench.Classname, "FabrickatorWorkbench")
        self.assertIn("class FabrickatorWorkbench(FreeCADGui.Workbench)",
                      (ROOT / workbench.Subdirectory / "InitGui.py").read_text())
        self.assertTrue((ROOT / workbench.Icon).is_file(), workbench.Icon)
        self.assertEqual(workbench.FreeCADMin, "0.20.0")
        # each python package pinned in requirements.txt by that name (or cadquery-ocp for OCP)
        pinned = {line.split("==")[0].lower() for line in (ROOT / "requirements.txt").read_text().splitlines()
                  if "==" in line}
        names = [depend["package"] for depend in workbench.Depend]
        self.assertEqual(len(names), 11, names)
        self.assertLessEqual({name.lower() for name in names}, pinned)
        written = ElementTree.parse(ROOT / "package.xml").getroot()
        namespace = {"p": "https://wiki.freecad.org/Package_Metadata"}
        for depend in written.findall("p:content/p:workbench/p:depend", namespace):
            self.assertEqual((depend.get("type"), depend.get("optional")), ("python", "true"), depend.text)
        if "optional" in workbench.Depend[0]:
            # FreeCAD 1.0 reads the type and the optional flag (0.20 reads neither)
            self.assertEqual({(d["type"], d["optional"]) for d in workbench.Depend}, {("python", True)})
            self.assertEqual(workbench.PythonMin, "3.10.0")
        else:
            self.assertLess([int(n) for n in App.Version()[:2]], [1, 0], "this FreeCAD should read the optional flag")
