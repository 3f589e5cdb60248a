"""App tests (freecadcmd) of the force check in the workbench (issue 14): Load objects, the
Fabrication's Ground and Clutch, and the same verdict as the command line.

    freecadcmd -u TMPDIR/user.cfg -t TestFabrickatorApp.TestLoads --module-path=REPO

(``make test-app`` runs them: TestFabrickatorApp imports this module.)

The part is an L: a 16 x 16 x 9.6 mm block (a 2x2 brick) with a 48 x 16 x 3.2 mm
arm on top (a 2x6 plate reaching 32 mm past the block), on a baseplate.  A
mass on the arm's tip pulls the plate's studs off the brick: 100 g holds,
1 kg does not.
"""

from __future__ import annotations

import json
import os
import subprocess
from pathlib import Path

import FreeCAD as App

import FabrickatorWorkbench as fab
from TestFabrickatorApp import FabrickatorTestCase, padded_body
from TestFabrickatorParity import PYTHON, ROOT

#: The arm's tip (Source mm): where the tests put their loads.
TIP = (40.0, 0.0, 12.8, 48.0, 16.0, 16.0)


def l_shape(doc):
    """A Part feature: a 16 x 16 x 9.6 block with a 48 x 16 x 3.2 arm on top, from x = 0."""
    import Part

    block = Part.makeBox(16, 16, 9.6)
    arm = Part.makeBox(48, 16, 3.2, App.Vector(0, 0, 9.6))
    source = doc.addObject("Part::Feature", "L")
    source.Shape = block.fuse(arm).removeSplitter()
    return source


def force(f) -> dict:
    return fab.report(f)["stability"]["force"]


class TestLoads(FabrickatorTestCase):
    def computed(self, source=None, **settings):
        f = fab.make_fabrication(source or padded_body(self.doc)[0], slice_print_times=False)
        for name, value in settings.items():
            setattr(f, name, value)
        self.doc.recompute()
        self.assertTrue(f.Status.startswith("ok"), f.Status)
        return f

    def test_a_load_adds_its_mass_and_sits_under_its_fabrication(self):
        f = self.computed()
        before = force(f)
        self.assertEqual(before["loads"], [])
        self.assertTrue(f.Stands)
        load = fab.make_load(self.doc, f, (0, 0, 19.2, 40, 24, 22), 170)
        self.assertEqual(fab.loads(f), [load])
        self.assertAlmostEqual(load.Shape.Volume, 40 * 24 * 2.8, delta=1e-6)
        self.doc.recompute()
        self.assertTrue(f.Status.startswith("ok"), f.Status)
        after = force(f)
        # the force check carries exactly the bricks and the load: mass is conserved
        self.assertAlmostEqual(after["mass_g"], before["mass_g"] + 170.0, delta=0.01)
        self.assertEqual(after["loads"], [{"box_mm": [[0.0, 0.0, 19.2], [40.0, 24.0, 22.0]],
                                           "grams": 170.0}])
        groups = [g for g in f.Contents if getattr(g, "FabrickatorRole", "") == "Loads"]
        self.assertEqual([list(g.Group) for g in groups], [[load]])
        self.assertEqual(fab.fabrication_of(load), f)
        self.assertEqual(set(after["utilisation"]), {str(b.BrickId) for b in fab.bricks(f)})
        self.assertIn("with 179 g", f.Forces)

    def test_a_heavy_load_on_the_arm_fails_and_a_light_one_holds(self):
        f = self.computed(l_shape(self.doc), Ground="baseplate")
        fab.make_load(self.doc, f, TIP, 100)
        self.doc.recompute()
        light = force(f)
        self.assertTrue(light["stable"], light)
        self.assertTrue(f.Stands)
        self.assertEqual(f.FailingBricks, 0)
        self.assertGreater(light["max_utilisation"], 0.2)
        fab.loads(f)[0].Mass = 1000.0
        self.doc.recompute()
        heavy = force(f)
        self.assertFalse(heavy["stable"])
        self.assertFalse(f.Stands)
        plate = [b for b in fab.bricks(f) if b.Cell[2] == 3]
        # the joint that gives is the one between the plate and the brick under it
        self.assertIn(plate[0].BrickId, heavy["failing_bricks"])
        self.assertEqual(f.FailingBricks, len(heavy["failing_bricks"]))
        self.assertIn("does not stand on a baseplate", f.Forces)
        # the arm works ten times as hard with ten times the mass (the plate's own 3 g aside)
        self.assertAlmostEqual(heavy["max_utilisation"] / light["max_utilisation"], 10.0, delta=0.5)
        stressed = dict((o.Name, u) for o, u in f.Proxy.utilisations(f))
        self.assertGreater(stressed[plate[0].Name], 1.0)

    def test_ground_and_clutch_reach_the_core_and_default_to_the_one_table(self):
        from core.request import DEFAULTS

        f = fab.make_fabrication(l_shape(self.doc), slice_print_times=False)
        self.assertEqual(f.Ground, DEFAULTS["ground"])
        self.assertAlmostEqual(float(f.Clutch.getValueAs("N")), DEFAULTS["clutch_n"])
        self.doc.recompute()
        self.assertEqual(force(f)["ground"], "table")
        self.assertFalse(f.Stands, "the arm tips the L over on a table")
        f.Ground = "baseplate"
        f.Clutch = App.Units.Quantity("0.5 N")
        self.doc.recompute()
        self.assertEqual((force(f)["ground"], force(f)["clutch_n"]), ("baseplate", 0.5))
        self.assertTrue(f.Stands)
        f.Clutch = 0.0
        self.doc.recompute()
        self.assertTrue(f.Status.startswith("failed"), f.Status)
        self.assertIn("--clutch", f.Status)
        self.assertAlmostEqual(float(f.Clutch.getValueAs("N")), 0.5)

    def test_a_load_touching_no_brick_fails_and_keeps_the_result(self):
        f = self.computed()
        report = f.ReportJson
        fab.make_load(self.doc, f, (100, 100, 100, 110, 110, 110), 50)
        self.doc.recompute()
        self.assertTrue(f.Status.startswith("failed"), f.Status)
        self.assertIn("touches no brick", f.Status)
        self.assertEqual(f.ReportJson, report)

    def test_a_load_from_bricks_or_a_shape_and_bad_masses(self):
        import Part

        f = self.computed()
        top = [b for b in fab.bricks(f) if b.Cell[2] + b.Size[2] == 6]
        load = fab.make_load(self.doc, f, top, 20)
        lo, hi = fab.brick_boxes(f, top)[0][:3], fab.brick_boxes(f, top)[0][3:]
        self.assertLessEqual(load.Shape.BoundBox.XMin, lo[0] + 1e-6)
        self.assertGreaterEqual(load.Shape.BoundBox.ZMax, hi[2] - 1e-6)
        phone = self.doc.addObject("Part::Feature", "Phone")
        phone.Shape = Part.makeBox(30, 10, 5, App.Vector(5, 7, 19.2))
        load = fab.make_load(self.doc, f, phone, 170)
        self.assertAlmostEqual(load.Shape.BoundBox.XMin, 5.0, delta=1e-9)
        self.assertAlmostEqual(load.Shape.Volume, 1500.0, delta=1e-6)
        # six brick ids are bricks, not a box
        every = fab.make_load(self.doc, f, [b.BrickId for b in fab.bricks(f)], 10)
        self.assertEqual(len(fab.bricks(f)), 6)
        self.assertAlmostEqual(every.Shape.BoundBox.ZMax, 19.2, delta=0.01)
        self.assertAlmostEqual(every.Shape.BoundBox.XMax - every.Shape.BoundBox.XMin, 40.0, delta=0.01)
        with self.assertRaises(ValueError):
            fab.make_load(self.doc, f, [0.0, 0.0, 0.0, 8.0, 8.0, 8.0], 10)
        for grams in (0, -5, float("nan")):
            with self.assertRaises(ValueError):
                fab.make_load(self.doc, f, phone, grams)
        self.doc.recompute()
        self.assertTrue(f.Status.startswith("ok"), f.Status)
        self.assertAlmostEqual(sum(x["grams"] for x in force(f)["loads"]), 200.0)

    def test_adding_a_load_is_one_undo_step(self):
        f = self.computed()
        report = f.ReportJson
        self.doc.openTransaction("Add load")
        load = fab.make_load(self.doc, f, (0, 0, 19.2, 40, 24, 22), 170)
        self.doc.recompute()
        self.doc.commitTransaction()
        name = load.Name
        self.assertNotEqual(f.ReportJson, report)
        self.doc.undo()
        self.assertIsNone(self.doc.getObject(name))
        self.assertEqual(fab.loads(f), [])
        self.assertEqual(f.ReportJson, report)
        self.doc.redo()
        self.assertEqual([x.Name for x in fab.loads(f)], [name])

    def test_properties_are_added_once_and_on_restore_of_an_older_document(self):
        from core.request import DEFAULTS
        from FabrickatorWorkbench.objects import fabrication
        from FabrickatorWorkbench.objects.properties import ensure

        f = self.computed()
        load = fab.make_load(self.doc, f, (0, 0, 19.2, 40, 24, 22), 170)
        self.doc.recompute()
        names = list(f.PropertiesList)
        self.assertEqual(ensure(f, fabrication.PROPERTIES), [])
        self.assertEqual(ensure(load, type(load.Proxy).PROPERTIES), [])
        self.assertEqual(list(f.PropertiesList), names)
        # a Fabrication saved before issue 14 had none of the force properties
        other = self.computed(l_shape(self.doc))
        new = ("Ground", "Clutch", "Loads", "Stands", "FailingBricks", "Forces")
        for name in new:
            other.removeProperty(name)
        path = self.path("forces.FCStd")
        self.doc.saveAs(path)
        App.closeDocument(self.doc.Name)
        self.doc = App.openDocument(path)
        restored = {f.Label: f for f in fab.fabrications(self.doc)}
        old = restored["L LEGO"]
        for name in new:
            self.assertIn(name, old.PropertiesList)
        self.assertEqual(old.Ground, DEFAULTS["ground"])
        self.assertAlmostEqual(float(old.Clutch.getValueAs("N")), DEFAULTS["clutch_n"])
        self.assertEqual(fab.loads(old), [])
        self.assertEqual(sorted(old.PropertiesList), sorted(names))
        kept = restored["Body LEGO"]
        self.assertEqual([(type(x.Proxy).__name__, x.Mass, round(x.Shape.BoundBox.XMax, 6))
                          for x in fab.loads(kept)], [("Load", 170.0, 40.0)])
        self.assertEqual([o.Name for o in self.doc.Objects if "Touched" in o.State], [])
        old.touch()
        self.doc.recompute()
        self.assertTrue(old.Status.startswith("ok"), old.Status)
        self.assertEqual(force(old)["ground"], "table")


class TestForceParity(FabrickatorTestCase):
    """The workbench and ``python -m core fabricate --load --ground`` give the same verdict."""

    def test_same_part_and_load_give_the_command_lines_utilisation(self):
        from FabrickatorWorkbench import bridge

        source = l_shape(self.doc)
        f = fab.make_fabrication(source, slice_print_times=False)
        f.Ground = "baseplate"
        fab.make_load(self.doc, f, TIP, 250)
        self.doc.recompute()
        self.assertTrue(f.Status.startswith("ok"), f.Status)
        folder = self.path("model")
        os.makedirs(folder)
        model = bridge.write_source(source, folder)
        out = self.path("cli")
        run = subprocess.run([str(PYTHON), "-m", "core", "fabricate", model, "--out", out,
                              "--no-picture", "--quiet", "--ground", "baseplate",
                              "--load=" + ",".join(f"{v:g}" for v in TIP) + ":250"],
                             cwd=str(ROOT), env=dict(os.environ, FABRICKATOR_SLICER="none"),
                             capture_output=True, text=True, timeout=600)
        self.assertEqual(run.returncode, 0, run.stderr)
        cli = json.loads(Path(out, "report.json").read_text())["stability"]["force"]
        mine = force(f)
        self.assertFalse(cli["stable"])
        for key in ("stable", "ground", "max_utilisation", "failing_bricks", "mass_g", "loads"):
            self.assertEqual(mine[key], cli[key], key)

    def test_the_arm_on_a_table_is_built_on_the_same_prop_as_on_the_command_line(self):
        """On a table the L tips over (its centre of mass is past the block's edge): its arm
        is built on a prop, which the finished part still needs.  The Fabrication keeps the
        props and the steps' words (the assembly panel shows them), as the command line's
        report has them."""
        from FabrickatorWorkbench import bridge

        source = l_shape(self.doc)
        f = fab.make_fabrication(source, slice_print_times=False)
        self.doc.recompute()
        self.assertTrue(f.Status.startswith("ok"), f.Status)
        self.assertFalse(f.Stands)
        words, props = fab.step_notes(f)
        self.assertTrue(props)
        for prop in props:
            (x0, y0, z0), (x1, y1, z1) = prop["box_mm"]
            self.assertGreaterEqual(x0, 16.0 - 1e-6)          # under the arm, past the block
            self.assertAlmostEqual(z0, 0.0)
            self.assertAlmostEqual(z1, 9.6)                  # up to the arm's bottom
            self.assertIsNone(prop["removed_after"])
            self.assertIn("Prop: before step", words[str(prop["step"])])
        folder = self.path("model")
        os.makedirs(folder)
        model = bridge.write_source(source, folder)
        out = self.path("cli")
        run = subprocess.run([str(PYTHON), "-m", "core", "fabricate", model, "--out", out,
                              "--no-picture", "--quiet"],
                             cwd=str(ROOT), env=dict(os.environ, FABRICKATOR_SLICER="none"),
                             capture_output=True, text=True, timeout=600)
        self.assertEqual(run.returncode, 0, run.stderr)
        build = json.loads(Path(out, "report.json").read_text())["stability"]["build"]
        cli = build["props"]
        self.assertEqual([{k: v for k, v in p.items() if k != "words"} for p in cli], props)
        # with its props left in, the finished part stands: the Forces words say so, as the
        # command line's report does
        finished = build["finished_with_props"]
        self.assertTrue(finished["stands"])
        self.assertEqual(finished["props_left_in"], len(props))
        self.assertIn(f"; with its {len(props)} prop(s) left in, it stands on a table", f.Forces)
        self.assertEqual(json.loads(f.ReportJson)["stability"]["build"]["finished_with_props"], finished)
