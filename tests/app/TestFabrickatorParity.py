"""The command line and the workbench run one pipeline: same part, same settings, same result.

    freecadcmd -u TMPDIR/user.cfg -t TestFabrickatorParity --module-path=REPO

A PartDesign Pad 100 x 60 x 40 mm with a through pocket gets a brushed
high-res region (a column of bricks).  The workbench's fresh run, its
iteration after the Pad grows to 48 mm and its export are compared with
``python -m core fabricate`` run in a subprocess (the workbench's venv) on the
same geometry with the same settings: the same bricks, printed parts and
steps.  And the Pad 40 -> 48 case of issue 12: after the change, the bricks
printed are those a fresh run with the same region prints (only the brushed
columns, not the new layers), and the highlighted bricks are the added ones.
"""

from __future__ import annotations

import csv
import json
import os
import subprocess
import tempfile
import unittest
from pathlib import Path

import FreeCAD as App

ROOT = Path(__file__).resolve().parents[2]

def _venv_python() -> Path:
    """The interpreter of the venv the workbench uses (``$FABRICKATOR_VENV`` or .venv)."""
    from FabrickatorWorkbench import deps

    return Path(deps.venv_dir()) / "bin" / "python"


PYTHON = _venv_python()


def fab():
    import FabrickatorWorkbench

    return FabrickatorWorkbench


def pocketed_pad(doc, height=40.0):
    """A PartDesign Body: a 100 x 60 rectangle padded by ``height``, with a 30 x 20
    pocket through all of it, off centre."""
    import Part
    import Sketcher

    body = doc.addObject("PartDesign::Body", "Body")
    xy = [f for f in body.Origin.OriginFeatures if f.Role == "XY_Plane"][0]

    def rectangle(name, x0, y0, x1, y1):
        sketch = body.newObject("Sketcher::SketchObject", name)
        support = "AttachmentSupport" if hasattr(sketch, "AttachmentSupport") else "Support"
        setattr(sketch, support, (xy, [""]))
        sketch.MapMode = "FlatFace"
        corners = [(x0, y0), (x1, y0), (x1, y1), (x0, y1)]
        for n in range(4):
            a, b = corners[n], corners[(n + 1) % 4]
            sketch.addGeometry(Part.LineSegment(App.Vector(*a, 0), App.Vector(*b, 0)), False)
        for n in range(4):
            sketch.addConstraint(Sketcher.Constraint("Coincident", n, 2, (n + 1) % 4, 1))
        return sketch

    outline = rectangle("Outline", 0, 0, 100, 60)
    pad = body.newObject("PartDesign::Pad", "Pad")
    pad.Profile = outline
    pad.Length = height
    doc.recompute()
    hole = rectangle("Hole", 55, 20, 85, 40)
    pocket = body.newObject("PartDesign::Pocket", "Pocket")
    pocket.Profile = hole
    pocket.Type = "ThroughAll"
    pocket.Reversed = True
    doc.recompute()
    if pocket.Shape.Volume > 100 * 60 * height - 1:
        pocket.Reversed = False
        doc.recompute()
    return body, pad


def bricks_of(layout_json: str | dict) -> list[tuple]:
    """The bricks of a layout.json as comparable rows (part, size, cell, kind, part id, step)."""
    data = json.loads(layout_json) if isinstance(layout_json, str) else layout_json
    return sorted((b["part"], tuple(b["size"]), tuple(b["cell"]), b["kind"], b["printed_part"],
                   b["step"]) for b in data["bricks"])


def printed_cells(layout_json: str | dict) -> set[tuple[int, int, int]]:
    data = json.loads(layout_json) if isinstance(layout_json, str) else layout_json
    out = set()
    for b in data["bricks"]:
        if b["kind"] == "printed":
            i, j, k = b["cell"]
            sx, sy, sz = b["size"]
            out |= {(i + a, j + c, k + d) for a in range(sx) for c in range(sy) for d in range(sz)}
    return out


class TestParity(unittest.TestCase):
    """One pipeline for the CLI and the workbench."""

    def setUp(self):
        self.doc = App.newDocument("FabrickatorParity")
        self.doc.UndoMode = 1
        self.tmp = tempfile.TemporaryDirectory(prefix="fabrickator-parity-")

    def tearDown(self):
        App.closeDocument(self.doc.Name)
        self.tmp.cleanup()

    def path(self, name: str) -> str:
        return os.path.join(self.tmp.name, name)

    def cli(self, model: str, out: str, boxes, previous: str | None = None, more=()) -> dict:
        """``python -m core fabricate`` on ``model`` with the Fabrication's settings (and the
        options ``more``); its outputs."""
        args = [str(PYTHON), "-m", "core", "fabricate", model, "--out", out, "--no-picture",
                "--quiet"] + [f"--high-res={','.join(f'{v:.6f}' for v in b)}" for b in boxes]
        args += list(more)
        if previous:
            args += ["--previous", previous]
        env = dict(os.environ, FABRICKATOR_SLICER="none")
        run = subprocess.run(args, cwd=str(ROOT), env=env, capture_output=True, text=True,
                             timeout=600)
        self.assertEqual(run.returncode, 0, run.stderr)
        return {"layout": json.loads(Path(out, "layout.json").read_text()),
                "report": json.loads(Path(out, "report.json").read_text())}

    def source_file(self, body, name: str) -> str:
        """The Source written as the workbench writes it for the core."""
        from FabrickatorWorkbench import bridge

        folder = self.path(name)
        os.makedirs(folder)
        return bridge.write_source(body, folder)

    def brushed(self, f) -> list[list[float]]:
        """Brush a column of bricks at the part's +x, -y corner; returns the region's boxes."""
        corner = [b for b in fab().bricks(f) if b.Cell[0] == max(x.Cell[0] for x in fab().bricks(f))
                  and b.Cell[1] == 0]
        region = fab().mark_high_res(f, bricks=corner)
        self.doc.recompute()
        self.assertTrue(f.Status.startswith("ok"), f.Status)
        boxes = fab().regions(f)[0].Boxes
        return [list(boxes[n:n + 6]) for n in range(0, len(boxes), 6)] if region else []

    def test_fresh_iteration_and_export_match_the_command_line(self):
        body, pad = pocketed_pad(self.doc)
        f = fab().make_fabrication(body, slice_print_times=False)
        self.doc.recompute()
        self.assertTrue(f.Status.startswith("ok"), f.Status)
        model40 = self.source_file(body, "v40")
        plain = self.path("cli-plain")
        self.assertEqual(bricks_of(f.LayoutJson), bricks_of(self.cli(model40, plain, [])["layout"]))

        # brushing is an iteration on the plain layout, as --previous with --high-res is
        boxes = self.brushed(f)
        self.assertTrue(boxes)
        self.assertGreater(f.PrintedParts, 0)
        self.assertIn("changes", fab().report(f))
        out40 = self.path("cli40")
        cli40 = self.cli(model40, out40, boxes, previous=plain)
        self.assertEqual(bricks_of(f.LayoutJson), bricks_of(cli40["layout"]))
        self.assertEqual(fab().report(f)["bricks"], cli40["report"]["bricks"])
        wb_parts = {p["id"]: p for p in fab().report(f)["printed_parts"]}
        for p in cli40["report"]["printed_parts"]:
            self.assertAlmostEqual(wb_parts[p["id"]]["volume_mm3"], p["volume_mm3"], delta=1e-3)
        printed40 = printed_cells(f.LayoutJson)

        pad.Length = 48.0
        self.doc.recompute()
        self.assertTrue(f.Status.startswith("ok"), f.Status)
        changes = fab().report(f)["changes"]
        model48 = self.source_file(body, "v48")
        cli48 = self.cli(model48, self.path("cli48"), boxes, previous=out40)
        self.assertEqual(bricks_of(f.LayoutJson), bricks_of(cli48["layout"]))
        self.assertEqual(changes["add"], cli48["report"]["changes"]["add"])
        self.assertEqual(changes["take_off"], cli48["report"]["changes"]["take_off"])

        # the Pad 40 -> 48 case: the highlighted bricks are the added ones, the new
        # layers among them, and only the brushed columns print, as in a fresh run
        highlighted = {b.BrickId for b in fab().bricks(f) if b.Changed}
        self.assertEqual(highlighted, {e["id"] for e in changes["add"]})
        new_layers = {b.BrickId for b in fab().bricks(f) if b.Cell[2] + b.Size[2] > 13}
        self.assertTrue(new_layers and new_layers <= highlighted)
        iterated = f.LayoutJson
        fresh = fab().make_fabrication(body, slice_print_times=False)
        fab().mark_high_res(fresh, boxes=boxes)
        self.doc.recompute()
        self.assertTrue(fresh.Status.startswith("ok"), fresh.Status)
        self.assertEqual(printed_cells(iterated), printed_cells(fresh.LayoutJson))
        self.assertEqual(printed_cells(iterated), printed40)
        self.assertEqual(f.Plates, fresh.Plates)
        self.assertEqual(bricks_of(f.LayoutJson), bricks_of(iterated))

        exported = self.path("export")
        fab().export(f, exported)
        self.assertEqual(bricks_of(Path(exported, "layout.json").read_text()),
                         bricks_of(cli48["layout"]))
        cli_files = {p.relative_to(self.path("cli48")).as_posix()
                     for p in Path(self.path("cli48")).rglob("*") if p.is_file()}
        wb_files = {p.relative_to(exported).as_posix() for p in Path(exported).rglob("*")
                    if p.is_file()}
        self.assertEqual({n for n in cli_files if not n.startswith("iteration/")} - {"layout.png"},
                         {n for n in wb_files if not n.startswith("iteration/")} - {"layout.png"})

    def test_an_inventory_gives_the_same_bricks_and_colours_as_the_command_line(self):
        body, _ = pocketed_pad(self.doc)
        box = self.path("box.csv")
        Path(box).write_text("Part,Color,Quantity\n3001,4,6\n3003,0,20\n3004,15,30\n"
                             "3024,71,50\n3023,72,40\n")
        f = fab().make_fabrication(body, slice_print_times=False)
        f.Inventory = [box]
        f.BuyColour = "Black"
        self.doc.recompute()
        self.assertTrue(f.Status.startswith("ok"), f.Status)
        cli = self.cli(self.source_file(body, "inv"), self.path("cli-inv"), [],
                       more=["--inventory", box, "--colour", "Black"])

        def coloured(data):
            data = json.loads(data) if isinstance(data, str) else data
            return sorted((b["part"], tuple(b["cell"]), b.get("colour"), b.get("owned"))
                          for b in data["bricks"])
        self.assertEqual(bricks_of(f.LayoutJson), bricks_of(cli["layout"]))
        self.assertEqual(coloured(f.LayoutJson), coloured(cli["layout"]))
        self.assertTrue(any(b[3] for b in coloured(f.LayoutJson)))
        self.assertEqual(fab().report(f)["inventory"]["to_buy"], cli["report"]["inventory"]["to_buy"])
        with open(Path(self.path("cli-inv"), "bom.csv"), newline="", encoding="utf-8") as rows:
            written = [(r["part"], r["color"], int(r["count"]), int(r["owned"]), int(r["to_buy"]))
                       for r in csv.DictReader(rows) if r["kind"] == "lego"]
        shown = [(r.part, r.color, r.count, r.owned, r.count - r.owned) for r in fab().bom(f)]
        self.assertEqual(shown, written)
        self.assertEqual(sum(r[4] for r in shown), cli["report"]["inventory"]["to_buy"])

    def test_properties_and_preferences_default_to_the_one_table(self):
        from core.request import DEFAULTS
        from FabrickatorWorkbench import preferences

        body, _ = pocketed_pad(self.doc)
        f = fab().make_fabrication(body)
        for prop, setting in (("Seed", "seed"), ("Scale", "scale"), ("FitGrid", "fit_grid"),
                              ("Hollow", "hollow"),
                              ("SecondsPerBrick", "seconds_per_brick"),
                              ("SecondsPerPart", "seconds_per_part"), ("StudFit", "stud_fit"),
                              ("SocketFit", "socket_fit")):
            value = getattr(f, prop)
            self.assertEqual(float(getattr(value, "Value", value)), float(DEFAULTS[setting]), prop)
        for name, setting in preferences.TABLE_FIELDS.items():
            self.assertEqual(preferences.default(name), DEFAULTS[setting], name)
        from FabrickatorWorkbench.objects import fabricate

        path = self.source_file(body, "defaults")
        job = fabricate.request(f, path, (), ())
        self.assertEqual(job.parts, "all")
        self.assertFalse(f.SlicePrintTimes)     # a recompute estimates unless asked to slice
        self.assertEqual(job.replace(parts=None), type(job)(
            model=path, previous_regions=False, iterate_moved=False, slicer="none",
            fit_source="the Fabrication's StudFit and SocketFit").checked())
        f.SlicePrintTimes = True
        self.assertEqual(fabricate.request(f, path, (), ()).slicer,
                         (preferences.get("SlicerPath") or "").strip() or None)


class TestLikeFreeCAD(unittest.TestCase):
    """Like FreeCAD's own features, a Fabrication hides its Source (deleting it shows it);
    layers are numbered from 1 everywhere a user reads them, as in the instructions."""

    def setUp(self):
        self.doc = App.newDocument("FabrickatorLikeFreeCAD")
        self.doc.UndoMode = 1

    def tearDown(self):
        App.closeDocument(self.doc.Name)

    def test_source_is_hidden_by_legofy_and_shown_when_the_fabrication_goes(self):
        body, _ = pocketed_pad(self.doc, height=9.6)
        self.assertTrue(body.Visibility)
        first = fab().make_fabrication(body, slice_print_times=False)
        second = fab().make_fabrication(body, slice_print_times=False)
        self.doc.recompute()
        self.assertFalse(body.Visibility)
        fab().remove_owned(first)
        self.doc.removeObject(first.Name)
        self.assertFalse(body.Visibility, "another Fabrication still builds it")
        fab().remove_owned(second)
        self.doc.removeObject(second.Name)
        self.assertTrue(body.Visibility)

    def test_layers_are_numbered_from_one_as_in_the_instructions(self):
        body, _ = pocketed_pad(self.doc, height=9.6)
        f = fab().make_fabrication(body, slice_print_times=False)
        self.doc.recompute()
        labels = sorted(g.Label for g in f.Contents if g.Label.startswith("Layer"))
        self.assertEqual(labels, ["Layer 1 (z 0.0 mm)", "Layer 2 (z 3.2 mm)", "Layer 3 (z 6.4 mm)"])
