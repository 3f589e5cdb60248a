"""Suggest high-res regions in the workbench, in ``freecadcmd``: one region per suggestion,
with its reason, in one undo step, the same boxes as ``python -m core suggest``.

A 48 x 48 x 9.6 mm plate with a Ø6.5 mm hole through it (Part API): the command's
region is the hole's, its boxes those the command line prints for the same solid
exported as STEP; Undo removes it in one step; the recompute prints the hole.

    freecadcmd -u TMPDIR/user.cfg -t TestFabrickatorApp.TestSuggest --module-path=REPO
"""

from __future__ import annotations

import json
import subprocess

import FreeCAD as App

from TestFabrickatorApp import ROOT, FabrickatorTestCase, fab
from TestFabrickatorParity import PYTHON


def holed_plate(doc):
    import Part

    plate = Part.makeBox(48, 48, 9.6, App.Vector(-24, -24, 0))
    hole = Part.makeCylinder(3.25, 9.6, App.Vector(-10, 0, 0))
    obj = doc.addObject("Part::Feature", "Plate")
    obj.Shape = plate.cut(hole)
    doc.recompute()
    return obj


class TestSuggest(FabrickatorTestCase):
    def test_one_region_per_suggestion_with_its_reason_as_the_cli_finds_it(self):
        from FabrickatorWorkbench.commands import suggest

        plate = holed_plate(self.doc)
        f = fab().make_fabrication(plate, slice_print_times=False)
        self.doc.recompute()
        regions_before = len(f.Regions)
        self.doc.UndoMode = 1
        made = suggest.suggest_regions(f)
        self.assertEqual(len(made), 1)
        region = made[0]
        self.assertEqual(region.Label, "Suggested 1: hole Ø6.5 mm, 9.6 mm deep")
        self.assertEqual(region.Reason, "hole Ø6.5 mm, 9.6 mm deep at axis z through (-10.0, 0.0, 4.8)")
        self.assertTrue(f.Status.startswith("ok"), f.Status)
        self.assertEqual(len(json.loads(f.ReportJson)["printed_parts"]), 1)

        step = self.path("plate.step")
        plate.Shape.exportStep(step)
        out = subprocess.run([str(PYTHON), "-m", "core", "suggest", step], cwd=str(ROOT),
                             capture_output=True, text=True, check=True).stdout
        cli = [float(v) for v in out.splitlines()[0].split("--high-res=")[1].split(",")]
        for mine, theirs in zip(region.Boxes, cli):
            self.assertAlmostEqual(mine, theirs, places=2)

        self.doc.undo()
        self.assertEqual(len(f.Regions), regions_before)
        self.assertFalse([o for o in self.doc.Objects if o.Label.startswith("Suggested")])
