"""App-level tests of the Fabrickator workbench, run by FreeCAD without GUI.

    freecadcmd -u TMPDIR/user.cfg -t TestFabrickatorApp --module-path=REPO

(``make test-app``; ``-u`` keeps the tests off the user's preferences.)

(``Init.py`` puts this folder on ``sys.path`` and registers the module.)
They build real geometry in FreeCAD (a PartDesign Body from a sketch, Part
primitives, a mesh, the bundled HMD example) and check the objects,
recompute, parametric changes of the Source, save/reopen, undo, failed
recomputes, export, and that FreeCAD's Plot and FEM still work with the
packages the workbench puts first.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
import unittest
from pathlib import Path

import FreeCAD as App

ROOT = Path(__file__).resolve().parents[2]
MODELS = ROOT.parent / "shared" / "models"
CELL = (8.0, 8.0, 3.2)
#: The demo's high-res boxes: the two lens mounts of examples/hmd.py (model mm).
HMD_LENS_MOUNTS = ((-54, 25, 25.5, -9, 36, 70.5), (9, 25, 25.5, 54, 36, 70.5))


def fab():
    import FabrickatorWorkbench

    return FabrickatorWorkbench


def padded_body(doc, length=40.0, width=24.0, height=19.2):
    """A PartDesign Body: a rectangle sketch (length x width, named constraints) padded by height."""
    import Part
    import Sketcher

    body = doc.addObject("PartDesign::Body", "Body")
    sketch = body.newObject("Sketcher::SketchObject", "Sketch")
    xy = [f for f in body.Origin.OriginFeatures if f.Role == "XY_Plane"][0]
    # FreeCAD 1.0 renamed Support to AttachmentSupport
    setattr(sketch, "AttachmentSupport" if hasattr(sketch, "AttachmentSupport") else "Support",
            (xy, [""]))
    sketch.MapMode = "FlatFace"
    corners = [(0, 0), (length, 0), (length, width), (0, width)]
    for n in range(4):
        a, b = corners[n], corners[(n + 1) % 4]
        sketch.addGeometry(Part.LineSegment(App.Vector(*a, 0), App.Vector(*b, 0)), False)
    for n in range(4):
        sketch.addConstraint(Sketcher.Constraint("Coincident", n, 2, (n + 1) % 4, 1))
    sketch.addConstraint(Sketcher.Constraint("Horizontal", 0))
    sketch.addConstraint(Sketcher.Constraint("Horizontal", 2))
    sketch.addConstraint(Sketcher.Constraint("Vertical", 1))
    sketch.addConstraint(Sketcher.Constraint("Vertical", 3))
    sketch.addConstraint(Sketcher.Constraint("Coincident", 0, 1, -1, 1))
    sketch.renameConstraint(sketch.addConstraint(
        Sketcher.Constraint("DistanceX", 0, 1, 0, 2, length)), "Length")
    sketch.renameConstraint(sketch.addConstraint(
        Sketcher.Constraint("DistanceY", 1, 1, 1, 2, width)), "Width")
    pad = body.newObject("PartDesign::Pad", "Pad")
    pad.Profile = sketch
    pad.Length = height
    doc.recompute()
    return body, sketch, pad


def plate_with_hole(doc):
    """A 48 x 32 x 9.6 mm Part box with a 10 mm bore through it at (36, 16): a Part::Cut."""
    plate = doc.addObject("Part::Box", "Plate")
    plate.Length, plate.Width, plate.Height = 48.0, 32.0, 9.6
    hole = doc.addObject("Part::Cylinder", "Hole")
    hole.Radius, hole.Height = 5.0, 9.6
    hole.Placement.Base = App.Vector(36, 16, 0)
    source = doc.addObject("Part::Cut", "Plate_with_hole")
    source.Base, source.Tool = plate, hole
    return source


def cell_box(f, brick):
    """The brick's cell box (min, max corner) in mm."""
    o, c = f.GridOrigin, f.CellSize
    lo = [o[n] + brick.Cell[n] * c[n] for n in range(3)]
    hi = [o[n] + (brick.Cell[n] + brick.Size[n]) * c[n] for n in range(3)]
    return lo, hi


def covered_cells(f) -> set:
    cells = set()
    for b in fab().bricks(f):
        i0, j0, k0 = b.Cell
        sx, sy, sz = b.Size
        cells |= {(i0 + i, j0 + j, k0 + k) for i in range(sx) for j in range(sy) for k in range(sz)}
    return cells


class FabrickatorTestCase(unittest.TestCase):
    """A fresh document per test, closed afterwards."""

    def setUp(self):
        self.doc = App.newDocument("FabrickatorTest")
        self.doc.UndoMode = 1
        self.tmp = tempfile.TemporaryDirectory(prefix="fabrickator-app-test-")

    def tearDown(self):
        App.closeDocument(self.doc.Name)
        self.tmp.cleanup()

    def path(self, name: str) -> str:
        return os.path.join(self.tmp.name, name)


class TestDependencies(unittest.TestCase):
    """The venv's packages come first and FreeCAD's own modules still work with them."""

    def test_venv_numpy_and_this_repositorys_core_are_used(self):
        from FabrickatorWorkbench import deps

        self.assertTrue(deps.check("the dependency test"))
        import cadquery  # noqa: F401
        import numpy

        import core
        self.assertGreaterEqual(int(numpy.__version__.split(".")[0]), 2)
        self.assertTrue(numpy.__file__.startswith(deps.site_packages()))
        self.assertEqual(Path(core.__file__).resolve(), ROOT / "core" / "__init__.py")

    def test_fem_works_with_the_venv_numpy(self):
        import numpy
        import ObjectsFem
        from femresult import resulttools
        from femtools import femutils  # noqa: F401

        doc = App.newDocument("FemCheck")
        try:
            analysis = ObjectsFem.makeAnalysis(doc, "Analysis")
            material = ObjectsFem.makeMaterialSolid(doc, "Steel")
            mat = material.Material
            mat["YoungsModulus"] = "210000 MPa"
            material.Material = mat
            analysis.addObject(material)
            import Fem
            mesh = Fem.FemMesh()
            for n, p in enumerate([(0, 0, 0), (1, 0, 0), (0, 1, 0), (0, 0, 1)], start=1):
                mesh.addNode(*p, n)
            mesh.addVolume([1, 2, 3, 4])
            mesh_obj = doc.addObject("Fem::FemMeshObject", "Mesh")
            mesh_obj.FemMesh = mesh
            analysis.addObject(mesh_obj)
            doc.recompute()
            self.assertEqual(len(analysis.Group), 2)
            self.assertEqual(mesh_obj.FemMesh.VolumeCount, 1)
            self.assertAlmostEqual(resulttools.calculate_von_mises((100, 0, 0, 0, 0, 0)), 100.0)
            principal = resulttools.calculate_principal_stress_std((3, 2, 1, 0, 0, 0))
            self.assertAlmostEqual(float(principal[0]), 3.0)
            self.assertIs(resulttools.np, numpy)
        finally:
            App.closeDocument(doc.Name)

    def test_plot_module_imports_with_the_venv_matplotlib(self):
        import matplotlib

        import Plot
        from FabrickatorWorkbench import deps
        self.assertTrue(matplotlib.__file__.startswith(deps.site_packages()))
        self.assertTrue(hasattr(Plot, "plot"))
        from mpl_toolkits.mplot3d import Axes3D  # noqa: F401 - the namespace points at the venv
        import mpl_toolkits.mplot3d
        self.assertTrue(mpl_toolkits.mplot3d.__file__.startswith(deps.site_packages()))

    def test_missing_venv_is_one_line_naming_the_fix(self):
        script = Path(tempfile.mkdtemp(prefix="fabrickator-deps-")) / "missing.py"
        script.write_text(
            "import os, sys\n"
            f"sys.path.insert(0, {str(ROOT)!r})\n"
            f"exec(open({str(ROOT / 'Init.py')!r}).read())\n"
            "from FabrickatorWorkbench import deps\n"
            "print('CHECK', deps.check('Legofy'), flush=True)\n"
            "os._exit(0)\n")
        env = dict(os.environ, FABRICKATOR_VENV="/nonexistent/fabrickator-venv")
        run = subprocess.run(["freecadcmd", str(script)], capture_output=True, text=True,
                             env=env, timeout=120)
        out = run.stdout + run.stderr
        self.assertIn("CHECK False", out)
        self.assertIn("Legofy needs the Python package(s)", out)
        self.assertIn("-m venv --clear /nonexistent/fabrickator-venv && /nonexistent/fabrickator-venv/bin/python "
                      f"-m pip install --disable-pip-version-check --progress-bar off -r {ROOT}/requirements.txt",
                      out)
        self.assertNotIn("Traceback", out)


class TestPackage(unittest.TestCase):
    """What the Addon Manager reads."""

    def test_package_xml_names_the_workbench_icon_and_python_dependencies(self):
        meta = App.Metadata(str(ROOT / "package.xml"))
        self.assertEqual(meta.Name, "Fabrickator")
        self.assertTrue((ROOT / meta.Icon).is_file())
        workbench = meta.Content["workbench"][0]
        self.assertEqual(workbench.Classname, "FabrickatorWorkbench")
        self.assertIn("class FabrickatorWorkbench(", (ROOT / "InitGui.py").read_text())
        self.assertTrue((ROOT / workbench.Subdirectory / "InitGui.py").is_file())
        depends = {d["package"] for d in workbench.Depend}
        self.assertLessEqual({"numpy", "cadquery", "trimesh", "scipy", "manifold3d"}, depends)
        # each a Python package (FreeCAD 1.x reads the type) pinned in requirements.txt
        self.assertTrue(all(d.get("type", "python") == "python" for d in workbench.Depend))
        pinned = {line.split("==")[0].strip().lower()
                  for line in (ROOT / "requirements.txt").read_text().splitlines() if "==" in line}
        self.assertLessEqual({name.lower() for name in depends}, pinned)
        self.assertEqual(meta.Version, "0.1.0")
        self.assertEqual(meta.FreeCADMin, "0.20.0")
        self.assertEqual(workbench.FreeCADMin, "0.20.0")
        self.assertTrue(workbench.supportsCurrentFreeCAD())
        self.assertTrue((ROOT / workbench.Subdirectory / workbench.Icon).is_file())
        icons = ROOT / "FabrickatorWorkbench" / "resources" / "icons"
        for name in ("Legofy", "Layout", "HighResBrush", "MergeBrush", "SplitBrush", "Export",
                     "Assembly", "Report", "WatchFolder", "CalibrationStrip", "Load"):
            self.assertTrue((icons / f"{name}.svg").is_file(), name)


class TestFabrication(FabrickatorTestCase):
    """Objects, recompute and parametric changes."""

    def test_effort_property_follows_the_core_table(self):
        from core.request import DEFAULTS, EFFORTS
        from FabrickatorWorkbench.objects import fabricate

        body, _, _ = padded_body(self.doc)
        f = fab().make_fabrication(body)
        self.assertEqual(f.Effort, DEFAULTS["effort"])
        self.assertEqual(sorted(f.getEnumerationsOfProperty("Effort")), sorted(EFFORTS))
        f.Effort = "fast"
        self.assertEqual(fabricate.request(f, "part.stl", (), ()).effort, "fast")

    def test_printer_property_overrides_the_preference(self):
        """Printer, empty by default (the MK3S): the preference names the printer of every
        Fabrication, a Fabrication's own Printer wins, and the request carries it."""
        from FabrickatorWorkbench import preferences
        from FabrickatorWorkbench.objects import fabricate

        body, _, _ = padded_body(self.doc)
        f = fab().make_fabrication(body)
        self.assertEqual(f.Printer, "")
        try:
            self.assertIsNone(fabricate.request(f, "part.stl", (), ()).printer)
            preferences.set("Printer", "Original Prusa MINI & MINI+")
            self.assertEqual(fabricate.request(f, "part.stl", (), ()).printer,
                             "Original Prusa MINI & MINI+")
            f.Printer = "Creality Ender-3 (0.4 mm nozzle)"
            self.assertEqual(fabricate.request(f, "part.stl", (), ()).printer,
                             "Creality Ender-3 (0.4 mm nozzle)")
        finally:
            preferences.reset("Printer")

    def test_lower_bound_property_gives_the_bounds_of_the_command_line(self):
        """LowerBound, off by default as in the core's table: on, the Fabrication's report has
        the bounds ``--lower-bound`` gives for the same 5 x 3 stud box two bricks high (six
        bricks at least, proven, and six in one piece without weak points), and the words
        the command line prints."""
        from core.layout import search as improve
        from core.request import DEFAULTS
        from FabrickatorWorkbench.objects import fabricate

        body, _, _ = padded_body(self.doc)
        f = fab().make_fabrication(body)
        self.assertEqual(f.LowerBound, DEFAULTS["lower_bound"])
        self.doc.recompute()
        self.assertNotIn("one_piece", fab().report(f)["layout_quality"]["lower_bound"])
        f.LowerBound = True
        self.assertTrue(fabricate.request(f, "part.stl", (), ()).lower_bound)
        self.doc.recompute()
        self.assertTrue(f.Status.startswith("ok"), f.Status)
        quality = fab().report(f)["layout_quality"]
        self.assertEqual(quality["lower_bound"]["one_piece"]["bound"], 6)
        self.assertEqual(improve.bound_words(quality), (
            "lower bound: any layout needs at least 6 bricks (proven); a layout in one piece per "
            "region, with no weak point at least 6 (proven): these 6 are 1.000 times that "
            "(report.json layout_quality.lower_bound)"))

    def test_body_becomes_bricks_that_cover_every_cell_once(self):
        body, _, _ = padded_body(self.doc)
        f = fab().make_fabrication(body)
        self.doc.recompute()
        self.assertTrue(f.Status.startswith("ok"), f.Status)
        bricks = fab().bricks(f)
        self.assertEqual(len(bricks), f.Bricks)
        self.assertEqual(f.Plates, 5 * 3 * 6)
        cells = covered_cells(f)
        self.assertEqual(len(cells), f.Plates)
        self.assertEqual(sum(b.Size[0] * b.Size[1] * b.Size[2] for b in bricks), f.Plates)
        layers = {g.Layer: g for g in f.Contents if getattr(g, "FabrickatorRole", "") == "Layer"}
        for b in bricks:
            self.assertEqual(b.TypeId, "App::Link")
            self.assertEqual(b.LinkedObject.PartNumber, b.PartNumber)
            self.assertIn(b, layers[b.Layer].Group)
            self.assertEqual(b.Layer, b.Cell[2])
            self.assertGreaterEqual(b.Step, 1)
            self.assertEqual(b.Kind, "lego")
            import Part
            box = Part.getShape(b).BoundBox
            lo, hi = cell_box(f, b)
            self.assertAlmostEqual(box.XMin, lo[0] + 0.1, places=6)
            self.assertAlmostEqual(box.XMax, hi[0] - 0.1, places=6)
            self.assertAlmostEqual(box.YMin, lo[1] + 0.1, places=6)
            self.assertAlmostEqual(box.YMax, hi[1] - 0.1, places=6)
            self.assertAlmostEqual(box.ZMin, lo[2], places=6)
            self.assertAlmostEqual(box.ZMax, hi[2] + 1.7, places=6)
        protos = {b.LinkedObject.Name for b in bricks}
        self.assertLess(len(protos), len(bricks) + 1)
        report = fab().report(f)
        self.assertEqual(report["bricks"]["total"], len(bricks))
        self.assertEqual(len(fab().steps(f)), f.Steps)
        self.assertEqual(sorted(b for s in fab().steps(f) for b in s["bricks"]),
                         sorted(b.BrickId for b in bricks))
        self.assertEqual([o.Name for o in self.doc.Objects if "Touched" in o.State], [])

    def test_pad_length_and_sketch_dimension_changes_recompute_and_keep_bricks(self):
        body, sketch, pad = padded_body(self.doc)
        f = fab().make_fabrication(body)
        self.doc.recompute()
        before = {b.Name: tuple(b.Cell) for b in fab().bricks(f)}
        sketch.setDatum("Length", App.Units.Quantity("56 mm"))
        self.doc.recompute()
        self.assertTrue(f.Status.startswith("ok"), f.Status)
        self.assertEqual(f.Plates, 7 * 3 * 6)
        self.assertEqual(len(covered_cells(f)), f.Plates)
        changes = fab().report(f)["changes"]
        self.assertEqual(changes["transform"]["method"], "identity")
        self.assertEqual(changes["bricks_kept"], f.BricksKept)
        after = {b.Name: tuple(b.Cell) for b in fab().bricks(f)}
        kept = [n for n in after if n in before and before[n] == after[n]]
        self.assertEqual(len(kept), f.BricksKept)
        self.assertGreater(f.BricksKept, 0)
        self.assertEqual(f.BricksKept + f.BricksChanged, f.Bricks)
        self.assertTrue(all(b.Changed == (b.Name not in before) for b in fab().bricks(f)))
        pad.Length = 9.6
        self.doc.recompute()
        self.assertEqual(f.Plates, 7 * 3 * 3)
        self.assertEqual(max(b.Cell[2] + b.Size[2] for b in fab().bricks(f)), 3)

    def test_high_res_box_makes_an_exact_printed_part(self):
        import Part

        source = self.doc.addObject("Part::Cylinder", "Cylinder")
        source.Radius, source.Height = 20.0, 19.2
        self.doc.recompute()
        f = fab().make_fabrication(source)
        region = fab().mark_high_res(f, box=(10, -8, 0, 24, 8, 19.2))
        self.doc.recompute()
        self.assertTrue(f.Status.startswith("ok"), f.Status)
        parts = fab().printed_parts(f)
        self.assertEqual([p.PartId for p in parts], ["P1"])
        part = parts[0]
        self.assertTrue(part.Shape.isValid())
        self.assertGreater(part.Shape.Volume, 100.0)
        self.assertAlmostEqual(part.Shape.Volume, part.VolumeMm3, delta=1e-3 * part.VolumeMm3)
        # Full height, so it touches LEGO only sideways: anchor tabs in the bottom layer
        # reach under the LEGO beside it, and only their studs and the skin that carries
        # them leave the model: at most one cell's bottom layer and a stud per stud.
        outside = part.Shape.cut(source.Shape)
        import math
        per_stud = 8.0 * 8.0 * 3.2 + math.pi * (4.85 / 2) ** 2 * 1.7
        self.assertGreater(part.CompleteStuds, 0)
        self.assertLess(outside.Volume, part.CompleteStuds * per_stud)
        if outside.Volume > 1e-6:
            self.assertLess(outside.BoundBox.ZMin, 3.2 + 1e-3)
            self.assertLess(outside.BoundBox.ZMax, 3.2 + 1.7 + 0.4)
        printed = [b for b in fab().bricks(f) if b.Kind == "printed"]
        self.assertEqual(sorted(b.BrickId for b in printed), sorted(part.BrickIds))
        self.assertTrue(all(not b.Visibility and b.PrintedPart == "P1" for b in printed))
        self.assertGreater(part.PrintTime, 0)
        self.assertTrue(part.PrintTimeMethod)
        self.assertGreater(len(part.IncompleteStuds) + part.CompleteStuds, 0)
        self.assertIn(region, f.Regions)
        self.assertIsInstance(region.Shape, Part.Shape)
        self.assertGreaterEqual(part.Step, 1)
        self.assertGreater(f.SpeedUp, 0)

    def test_the_slicer_choice_travels_in_the_request_not_the_environment(self):
        from FabrickatorWorkbench import preferences

        source = self.doc.addObject("Part::Box", "Box")
        source.Length, source.Width, source.Height = 32.0, 16.0, 9.6
        self.doc.recompute()
        f = fab().make_fabrication(source, slice_print_times=False)
        fab().mark_high_res(f, box=(0, 0, 6.4, 8, 8, 9.6))
        missing = os.path.join(tempfile.gettempdir(), "fabrickator-no-such-slicer")
        saved_env, saved_path = os.environ.get("FABRICKATOR_SLICER"), preferences.get("SlicerPath")
        os.environ["FABRICKATOR_SLICER"] = "prusa-slicer"     # what the request must not follow
        def environment():      # engraving points fontconfig at the system's file once
            return {k: v for k, v in os.environ.items() if k != "FONTCONFIG_FILE"}

        try:
            before = environment()
            self.doc.recompute()
            self.assertEqual(environment(), before)
            self.assertTrue(f.Status.startswith("ok"), f.Status)
            (part,) = fab().printed_parts(f)
            self.assertTrue(part.PrintTimeMethod.startswith("estimate"), part.PrintTimeMethod)
            self.assertIn("slicer disabled", part.PrintTimeMethod)
            preferences.set("SlicerPath", missing)
            f.SlicePrintTimes, f.KeepLayout = True, False      # anew: the part is timed again
            self.doc.recompute()
            self.assertEqual(environment(), before)
            (part,) = fab().printed_parts(f)
            self.assertIn(f"slicer {missing} not found", part.PrintTimeMethod)
        finally:
            preferences.set("SlicerPath", saved_path)
            if saved_env is None:
                os.environ.pop("FABRICKATOR_SLICER", None)
            else:
                os.environ["FABRICKATOR_SLICER"] = saved_env

    def test_split_and_merge_brushes_change_the_printed_parts(self):
        source = self.doc.addObject("Part::Box", "Box")
        source.Length, source.Width, source.Height = 32.0, 16.0, 19.2
        self.doc.recompute()
        f = fab().make_fabrication(source, slice_print_times=False)
        fab().mark_high_res(f, box=(0, 0, 0, 32, 16, 19.2))
        self.doc.recompute()
        (part,) = fab().printed_parts(f)
        ids = list(part.BrickIds)
        self.assertGreater(len(ids), 1)
        fab().split_bricks(f, ids)
        self.doc.recompute()
        self.assertTrue(f.Status.startswith("ok"), f.Status)
        self.assertEqual(len(fab().printed_parts(f)), len(ids))
        fab().merge_bricks(f, ids)
        self.doc.recompute()
        (merged,) = fab().printed_parts(f)
        self.assertEqual(sorted(merged.BrickIds), sorted(ids))

    def test_regions_from_a_solid_and_from_faces_of_the_source(self):
        source = plate_with_hole(self.doc)
        self.doc.recompute()
        f = fab().make_fabrication(source)
        bore = [n for n, face in enumerate(source.Shape.Faces, 1)
                if face.Surface.__class__.__name__ == "Cylinder"]
        self.assertEqual(len(bore), 1)
        fab().mark_high_res(f, faces=(source, f"Face{bore[0]}"))
        self.doc.recompute()
        self.assertTrue(f.Status.startswith("ok"), f.Status)
        by_faces = fab().printed_parts(f)
        self.assertEqual(len(by_faces), 1)
        box = by_faces[0].Shape.BoundBox
        self.assertLessEqual(box.XMin, 31.0)
        self.assertGreaterEqual(box.XMax, 41.0)
        self.assertGreater(box.XMin, 8.0)

        marker = self.doc.addObject("Part::Box", "Marker")
        marker.Length, marker.Width, marker.Height = 4.0, 4.0, 4.0
        marker.Placement.Base = App.Vector(2, 2, 2)
        self.doc.recompute()
        fab().mark_high_res(f, solid=marker)
        self.doc.recompute()
        ids = sorted(p.PartId for p in fab().printed_parts(f))
        self.assertEqual(ids, ["P1", "P2"])
        corner = [p for p in fab().printed_parts(f) if p.Shape.BoundBox.XMin < 1.0]
        self.assertEqual(len(corner), 1)

    def test_face_skins_are_what_freecads_offset_of_the_faces_gives(self):
        """The core's face skins (core.face_region, OpenCascade's offset in the venv) are
        FreeCAD's own ``makeOffsetShape(-skin, 0.01, fill=True)`` of each face: the same
        volume at the same place, inside the part, for flat, holed and bored faces of a
        moved and turned Source."""
        from core.face_region import SKIN_MM
        from FabrickatorWorkbench.objects import high_res_region

        source = plate_with_hole(self.doc)
        source.Placement = App.Placement(App.Vector(5, -3, 2), App.Rotation(App.Vector(0, 0, 1), 30))
        self.doc.recompute()
        names = [f"Face{n}" for n in range(1, len(source.Shape.Faces) + 1)]
        region = fab().mark_high_res(fab().make_fabrication(source), faces=[(source, names)])
        skins = high_res_region.face_skins(region)
        self.assertEqual(len(skins), len(names))
        for name, skin in zip(names, skins):
            expected = source.getSubObject(name).makeOffsetShape(-SKIN_MM, 0.01, fill=True)
            volume = expected.Volume
            self.assertGreater(volume, 0.0, name)
            self.assertAlmostEqual(skin.Volume, volume, delta=1e-4 * volume, msg=name)
            self.assertAlmostEqual(skin.common(expected).Volume, volume, delta=1e-4 * volume,
                                   msg=name)
            self.assertAlmostEqual(skin.common(source.Shape).Volume, volume, delta=1e-4 * volume,
                                   msg=name)
        self.assertAlmostEqual(region.Shape.Volume, sum(s.Volume for s in skins), delta=1e-6 *
                               region.Shape.Volume)

    def test_mesh_source_with_a_printed_part(self):
        import Mesh

        mesh = self.doc.addObject("Mesh::Feature", "MeshBox")
        mesh.Mesh = Mesh.createBox(40.0, 24.0, 12.8)
        mesh.Placement.Base = App.Vector(20, 12, 6.4)
        self.doc.recompute()
        f = fab().make_fabrication(mesh)
        fab().mark_high_res(f, box=(0, 0, 0, 8, 8, 3.2))
        self.doc.recompute()
        self.assertTrue(f.Status.startswith("ok"), f.Status)
        self.assertEqual(f.Plates, 5 * 3 * 4)
        self.assertAlmostEqual(f.GridOrigin.x, 0.0, places=6)
        parts = fab().printed_parts(f)
        self.assertEqual(len(parts), 1)
        self.assertTrue(parts[0].Shape.isClosed())
        self.assertGreater(parts[0].Shape.Volume, 0.0)

    def test_a_mesh_turned_upright_by_its_placement_is_built_as_the_cli_builds_it_with_up(self):
        """A 16 x 48 x 16 mm mesh box lying along y, turned upright by its Placement (a quarter
        turn about x): the Fabrication stands it 15 plate layers tall on 2 x 2 studs, as
        ``fabricate --up y`` builds the same box lying in a file (tests/core/test_cli.py)."""
        import Mesh

        mesh = self.doc.addObject("Mesh::Feature", "Lying")
        mesh.Mesh = Mesh.createBox(16.0, 48.0, 16.0)
        mesh.Placement = App.Placement(App.Vector(0, 0, 0), App.Rotation(App.Vector(1, 0, 0), 90))
        self.doc.recompute()
        f = fab().make_fabrication(mesh)
        self.doc.recompute()
        self.assertTrue(f.Status.startswith("ok"), f.Status)
        self.assertEqual(json.loads(f.LayoutJson)["shape"], [2, 2, 15])
        self.assertEqual(f.Plates, 2 * 2 * 15)

    def test_failed_recompute_keeps_the_result_and_the_parameters(self):
        body, _, _ = padded_body(self.doc)
        f = fab().make_fabrication(body, brick_set="all")
        self.doc.recompute()
        names = sorted(b.Name for b in fab().bricks(f))
        layout = f.LayoutJson
        f.BrickSet = "3001,3003"
        self.doc.recompute()
        self.assertTrue(f.Status.startswith("failed"), f.Status)
        self.assertIn("3024", f.Status)
        self.assertEqual(f.BrickSet, "all")
        self.assertEqual(sorted(b.Name for b in fab().bricks(f)), names)
        self.assertEqual(f.LayoutJson, layout)
        sketchy = self.doc.addObject("Part::Feature", "JustAFace")
        import Part
        sketchy.Shape = Part.makePlane(10, 10)
        f.Source = sketchy
        self.doc.recompute()
        self.assertIn("has no solid and no mesh", f.Status)
        self.assertEqual(f.LayoutJson, layout)

    def test_memory_running_out_is_one_line_and_keeps_the_result(self):
        """Memory the system refuses mid-run is not a bug: one line in the Report view and
        Status, the previous result and parameters kept (as the command line's exit 2)."""
        from FabrickatorWorkbench.objects import fabricate as fabricate_object
        body, _, _ = padded_body(self.doc)
        f = fab().make_fabrication(body, brick_set="all")
        self.doc.recompute()
        layout, seed = f.LayoutJson, f.Seed

        def no_memory(obj):
            raise MemoryError("Unable to allocate 155. MiB for an array")

        run_core = fabricate_object.run_core
        fabricate_object.run_core = no_memory
        try:
            f.Seed = seed + 1
            self.doc.recompute()
        finally:
            fabricate_object.run_core = run_core
        self.assertTrue(f.Status.startswith("failed, previous result kept: not enough memory: "
                                            "MemoryError: Unable to allocate"), f.Status)
        self.assertNotIn("bug", f.Status)
        self.assertEqual(f.LayoutJson, layout)
        self.assertEqual(f.Seed, seed)

    def test_brick_set_and_seed_are_used(self):
        body, _, _ = padded_body(self.doc)
        f = fab().make_fabrication(body, brick_set="plates")
        self.doc.recompute()
        self.assertTrue(all(b.Size[2] == 1 for b in fab().bricks(f)))
        self.assertTrue(all(b.PartNumber in {"3024", "3023", "3623", "3710", "3666", "3460", "3022",
                                             "3021", "3020", "3795", "3034"}
                            for b in fab().bricks(f)))


def near(lo, hi, region, margin=(8.0, 8.0, 9.6)) -> bool:
    """Whether the box lo..hi lies within ``margin`` (one brick) of the box ``region``."""
    return all(hi[n] > region[0][n] - margin[n] - 1e-6 and lo[n] < region[1][n] + margin[n] + 1e-6
               for n in range(3))


def same_placement(a, b, tol=1e-9) -> bool:
    return (a.Base - b.Base).Length <= tol and all(abs(x - y) <= tol
                                                    for x, y in zip(a.Rotation.Q, b.Rotation.Q))


class TestIteration(FabrickatorTestCase):
    """Design iteration (issue 6): a parametric edit of the Source keeps the layout where
    nothing changed, highlights the new bricks, shows the removed ones as ghosts and
    marks only the printed parts to reprint."""

    #: The edit: the Pad of a 40 x 24 x 19.2 mm Body grows to 28.8 mm.
    TALLER = 28.8
    EDITED = ((0.0, 0.0, 19.2), (40.0, 24.0, 28.8))

    def raise_pad(self, boxes=()):
        body, _, pad = padded_body(self.doc)
        f = fab().make_fabrication(body, slice_print_times=False)
        for box in boxes:
            fab().mark_high_res(f, box=box)
        self.doc.recompute()
        self.assertTrue(f.Status.startswith("ok"), f.Status)
        self.assertEqual(fab().ghosts(f), [])
        self.assertFalse(any(b.Changed for b in fab().bricks(f)))
        before = {b.BrickId: (b.Name, b.PartNumber, App.Placement(b.Placement))
                  for b in fab().bricks(f)}
        pad.Length = self.TALLER
        self.doc.recompute()
        self.assertTrue(f.Status.startswith("ok"), f.Status)
        return f, before

    def test_taller_pad_highlights_the_added_bricks_near_the_edit_and_ghosts_the_removed(self):
        from FabrickatorWorkbench.objects.tree import HIGHLIGHT_COLOUR

        f, before = self.raise_pad()
        changes = fab().report(f)["changes"]
        self.assertEqual(changes["transform"]["method"], "identity")
        added = {e["id"] for e in changes["add"]}
        taken = {e["id"] for e in changes["take_off"]}
        bricks = fab().bricks(f)
        highlighted = {b.BrickId for b in bricks if b.Changed}
        self.assertTrue(added)
        self.assertEqual(highlighted, added)
        self.assertEqual(f.BricksChanged, len(added))
        self.assertLess(len(added), len(bricks))
        self.assertEqual(len(covered_cells(f)), f.Plates)
        self.assertEqual(f.Plates, 5 * 3 * 9)
        for b in bricks:
            green = tuple(round(c, 3) for c in b.LinkedObject.Color[:3]) == tuple(
                round(round(c * 255) / 255, 3) for c in HIGHLIGHT_COLOUR)
            self.assertEqual(green, b.Changed, b.Label)
            if b.Changed:
                self.assertTrue(near(*cell_box(f, b), self.EDITED), (b.Label, cell_box(f, b)))
            else:
                name, part, where = before[b.BrickId]
                self.assertEqual((b.Name, b.PartNumber), (name, part))
                self.assertTrue(same_placement(b.Placement, where), b.Label)
        self.assertEqual(f.BricksKept, len(bricks) - len(added))
        self.assertEqual(changes["bricks_kept"], f.BricksKept)
        ghosts = fab().ghosts(f)
        self.assertEqual({g.BrickId for g in ghosts}, taken)
        self.assertEqual(len(ghosts), len(taken))
        for g in ghosts:
            self.assertNotIn(g, bricks)
            name, part, where = before[g.BrickId]
            self.assertEqual(g.LinkedObject.PartNumber, part)
            self.assertTrue(same_placement(g.Placement, where), g.Label)
            self.assertIsNone(self.doc.getObject(name))
        lines = list(f.Changes)
        self.assertEqual([line.split(":")[0] for line in lines], ["take off", "add", "reprint", "keep"])
        self.assertIn(f"{len(added)} brick(s)", lines[1])
        self.assertIn(f"{len(taken)} brick(s)" if taken else "no brick", lines[0])

        path = self.path("iterated.FCStd")
        self.doc.saveAs(path)
        App.closeDocument(self.doc.Name)
        self.doc = App.openDocument(path)
        f = fab().fabrications(self.doc)[0]
        self.assertEqual([o.Name for o in self.doc.Objects if "Touched" in o.State], [])
        self.assertEqual({g.BrickId for g in fab().ghosts(f)}, taken)
        self.assertEqual({b.BrickId for b in fab().bricks(f) if b.Changed}, added)
        self.assertEqual(list(f.Changes), lines)

        sketch = self.doc.getObject("Sketch")
        before = {b.BrickId: (b.Name, b.PartNumber, App.Placement(b.Placement))
                  for b in fab().bricks(f)}
        sketch.setDatum("Length", App.Units.Quantity("32 mm"))
        self.doc.recompute()
        self.assertTrue(f.Status.startswith("ok"), f.Status)
        changes = fab().report(f)["changes"]
        taken = {e["id"] for e in changes["take_off"]}
        self.assertTrue(taken)
        ghosts = fab().ghosts(f)
        self.assertEqual({g.BrickId for g in ghosts}, taken)
        self.assertEqual(len(ghosts), len(taken))
        for g in ghosts:
            name, part, where = before[g.BrickId]
            self.assertEqual(g.LinkedObject.PartNumber, part)
            self.assertTrue(same_placement(g.Placement, where), g.Label)
            self.assertTrue(near(*cell_box(f, g), ((32.0, 0.0, 0.0), (40.0, 24.0, 28.8))), g.Label)
        self.assertEqual({b.BrickId for b in fab().bricks(f) if b.Changed},
                         {e["id"] for e in changes["add"]})
        for b in fab().bricks(f):
            if not b.Changed:
                self.assertEqual(before[b.BrickId][0], b.Name)
        self.assertEqual(len(covered_cells(f)), f.Plates)

        names = {b.BrickId: b.Name for b in fab().bricks(f)}
        self.assertTrue(fab().recompute(f))
        self.assertEqual(fab().ghosts(f), [])
        self.assertFalse(any(b.Changed for b in fab().bricks(f)))
        self.assertEqual({b.BrickId: b.Name for b in fab().bricks(f)}, names)
        self.assertEqual(f.Changes[:2], ["take off: no brick", "add: no brick"])
        self.assertEqual([g.Name for g in f.Contents if "Removed" in g.Label], [])

    def test_printed_part_away_from_the_edit_is_not_reprinted(self):
        f, _ = self.raise_pad(boxes=[(0, 0, 0, 8, 8, 3.2), (32, 16, 16, 40, 24, 19.2)])
        taken = {e["id"] for e in fab().report(f)["changes"]["take_off"]}
        self.assertEqual({g.BrickId for g in fab().ghosts(f)}, taken)
        parts = {p.PartId: p for p in fab().printed_parts(f)}
        self.assertEqual(sorted(parts), ["P1", "P2"])
        bottom = next(p for p in parts.values() if p.Shape.BoundBox.ZMax < 9.6)
        top = next(p for p in parts.values() if p is not bottom)
        self.assertFalse(bottom.Reprint)
        self.assertEqual(bottom.Label, bottom.PartId)
        self.assertTrue(top.Reprint)
        self.assertEqual(top.Label, f"{top.PartId} (reprint)")
        self.assertGreater(top.Shape.BoundBox.ZMax, 19.2)
        self.assertEqual(fab().report(f)["changes"]["parts_reprinted"], [top.PartId])
        self.assertEqual(f.Changes[2], f"reprint: {top.PartId}")
        self.assertIn(f"printed part(s) {bottom.PartId} as printed", f.Changes[3])
        self.assertFalse(any(b.Changed for b in fab().bricks(f) if b.PrintedPart == bottom.PartId))

    def test_clear_changes_takes_the_marks_away(self):
        f, _ = self.raise_pad()
        highlighted = [b for b in fab().bricks(f) if b.Changed]
        self.green = {b.LinkedObject.Name for b in highlighted}
        self.assertEqual(fab().clear_changes(f), len(highlighted))
        self.assertEqual(fab().ghosts(f), [])
        self.assertFalse(any(b.Changed for b in fab().bricks(f)))
        self.assertTrue(highlighted)
        self.assertTrue(all(b.LinkedObject.PartNumber == b.PartNumber for b in highlighted))
        self.assertEqual({b.LinkedObject.Name for b in highlighted} & self.green, set())
        self.assertEqual(list(f.Changes), [])
        self.assertEqual([o.Name for o in self.doc.Objects if "Touched" in o.State], [])

    def test_a_new_version_of_a_watched_file_iterates_its_fabrication(self):
        import trimesh

        folder = Path(self.path("watched"))
        folder.mkdir()
        block = trimesh.creation.box((48.0, 32.0, 9.6))
        block.apply_translation(-block.bounds[0])
        block.export(folder / "bracket.stl")
        source, (f,), new = fab().feed_file(folder / "bracket.stl", self.doc)
        self.assertTrue(new)
        self.doc.recompute()
        self.assertEqual(f.Plates, 6 * 4 * 3)
        kept = {b.BrickId: b.Name for b in fab().bricks(f)}
        longer = trimesh.creation.box((64.0, 32.0, 9.6))
        longer.apply_translation(-longer.bounds[0])
        longer.export(folder / "bracket_v2.stl")
        again, fabs, new = fab().feed_file(folder / "bracket_v2.stl", self.doc)
        self.assertFalse(new)
        self.assertEqual((again, fabs), (source, [f]))
        self.doc.recompute()
        self.assertTrue(f.Status.startswith("ok"), f.Status)
        self.assertEqual(f.Plates, 8 * 4 * 3)
        self.assertEqual(len(fab().fabrications(self.doc)), 1)
        changes = fab().report(f)["changes"]
        self.assertEqual(changes["transform"]["method"], "identity")
        self.assertEqual({b.BrickId for b in fab().bricks(f) if b.Changed},
                         {e["id"] for e in changes["add"]})
        for b in fab().bricks(f):
            if not b.Changed:
                self.assertEqual(kept.get(b.BrickId), b.Name)
        self.assertEqual(f.BricksKept, changes["bricks_kept"])
        self.assertGreater(f.BricksKept, 0)
        self.assertEqual(fab().model_name("bracket (1).stl"), "bracket")
        self.assertEqual(fab().model_name("gear2.stl"), "gear2")
        other, (g,), new = fab().feed_file(_copy(folder / "bracket.stl", folder / "gear.stl"),
                                           self.doc)
        self.assertTrue(new)
        self.assertNotEqual(g, f)


def _copy(a: Path, b: Path) -> Path:
    b.write_bytes(a.read_bytes())
    return b


class TestDocument(FabrickatorTestCase):
    """Save and reopen, undo and redo, export."""

    def test_save_and_reopen_restore_everything_without_recompute(self):
        body, _, _ = padded_body(self.doc)
        f = fab().make_fabrication(body)
        fab().mark_high_res(f, box=(0, 0, 12.8, 8, 8, 19.2))
        self.doc.recompute()
        saved = {
            "layout": f.LayoutJson, "report": f.ReportJson, "steps": f.StepsJson,
            "bricks": sorted((b.Name, b.PartNumber, tuple(b.Cell), b.Kind, b.Step, b.LinkedObject.Name)
                             for b in fab().bricks(f)),
            "parts": [(p.PartId, round(p.Shape.Volume, 6), p.CompleteStuds) for p in fab().printed_parts(f)],
            "regions": [tuple(r.Boxes) for r in f.Regions],
        }
        path = self.path("saved.FCStd")
        self.doc.saveAs(path)
        name = self.doc.Name
        App.closeDocument(name)
        self.doc = App.openDocument(path)
        f = fab().fabrications(self.doc)[0]
        self.assertEqual([o.Name for o in self.doc.Objects if "Touched" in o.State], [])
        self.assertEqual(f.LayoutJson, saved["layout"])
        self.assertEqual(f.ReportJson, saved["report"])
        self.assertEqual(f.StepsJson, saved["steps"])
        self.assertEqual(sorted((b.Name, b.PartNumber, tuple(b.Cell), b.Kind, b.Step, b.LinkedObject.Name)
                                for b in fab().bricks(f)), saved["bricks"])
        self.assertEqual([(p.PartId, round(p.Shape.Volume, 6), p.CompleteStuds)
                          for p in fab().printed_parts(f)], saved["parts"])
        self.assertEqual([tuple(r.Boxes) for r in f.Regions], saved["regions"])
        self.assertEqual(type(f.Proxy).__name__, "Fabrication")
        self.assertEqual(fab().layout(f).to_json()["bricks"], json.loads(saved["layout"])["bricks"])

    def test_each_action_is_one_undo_step(self):
        body, _, _ = padded_body(self.doc)
        self.doc.openTransaction("Legofy")
        f = fab().make_fabrication(body)
        self.doc.recompute()
        self.doc.commitTransaction()
        plain = sorted(b.Name for b in fab().bricks(f))
        self.doc.openTransaction("High-res brush")
        fab().mark_high_res(f, bricks=[fab().bricks(f)[0]])
        self.doc.recompute()
        self.doc.commitTransaction()
        self.assertEqual(len(fab().printed_parts(f)), 1)
        marked = sorted(b.Name for b in fab().bricks(f))
        self.doc.undo()
        self.assertEqual(fab().printed_parts(f), [])
        self.assertEqual(list(f.Regions), [])
        self.assertEqual(sorted(b.Name for b in fab().bricks(f)), plain)
        self.doc.redo()
        self.assertEqual(len(fab().printed_parts(f)), 1)
        self.assertEqual(sorted(b.Name for b in fab().bricks(f)), marked)
        self.doc.undo()
        self.doc.undo()
        self.assertEqual(fab().fabrications(self.doc), [])
        self.assertEqual([o.Name for o in self.doc.Objects
                          if getattr(o, "FabrickatorRole", "") == "Brick"], [])

    def test_export_writes_parts_and_instructions(self):
        import trimesh

        body, _, _ = padded_body(self.doc)
        f = fab().make_fabrication(body)
        fab().mark_high_res(f, box=(0, 0, 12.8, 8, 8, 19.2))
        self.doc.recompute()
        out = Path(self.path("export"))
        written = fab().export(f, out)
        for name in ("parts", "layout.json", "layout.png", "report.json", "instructions.html",
                     "assembly.mpd", "bom.csv", "iteration"):
            self.assertIn(name, written)
        for name in ("parts/P1.stl", "parts/P1.step", "parts/plate-1.3mf", "layout.json",
                     "report.json", "instructions.html"):
            self.assertGreater((out / name).stat().st_size, 0)
        self.assertEqual(json.loads((out / "layout.json").read_text())["bricks"],
                         json.loads(f.LayoutJson)["bricks"])
        mesh = trimesh.load(out / "parts" / "P1.stl")
        self.assertTrue(mesh.is_watertight)
        self.assertAlmostEqual(mesh.volume, fab().printed_parts(f)[0].Shape.Volume, delta=1.0)
        import Part
        step = Part.read(str(out / "parts" / "P1.step"))
        self.assertAlmostEqual(step.Volume, fab().printed_parts(f)[0].Shape.Volume, delta=0.01)

    def test_removing_a_fabrication_removes_what_it_made(self):
        body, _, _ = padded_body(self.doc)
        f = fab().make_fabrication(body)
        self.doc.recompute()
        fab().remove_owned(f)
        self.doc.removeObject(f.Name)
        left = [o.Name for o in self.doc.Objects if hasattr(o, "FabrickatorRole")]
        self.assertEqual(left, [])


def stud_diameters(shape) -> list[float]:
    """Diameters of the vertical cylindrical faces of ``shape`` (its studs), sorted."""
    return sorted(round(2 * f.Surface.Radius, 6) for f in shape.Faces
                  if type(f.Surface).__name__ == "Cylinder" and abs(f.Surface.Axis.z) > 0.999)


def socket_widths(shape, z: float) -> list[tuple[float, float]]:
    """(x, y) widths of the inner loops (socket holes) of ``shape``'s section at height ``z``."""
    wires = shape.slice(App.Vector(0, 0, 1), z)
    outer = max(wires, key=lambda w: w.BoundBox.DiagonalLength)
    return sorted((round(w.BoundBox.XLength, 6), round(w.BoundBox.YLength, 6))
                  for w in wires if w is not outer and w.BoundBox.XLength < 6)


class TestFit(FabrickatorTestCase):
    """StudFit and SocketFit: defaults from core.parts.interfaces.Fit, preferences, the printed
    parts, old documents with a Clearance, and the calibration strip."""

    def setUp(self):
        super().setUp()
        from FabrickatorWorkbench import preferences

        self.preferences = preferences
        for name in ("StudFit", "SocketFit"):
            preferences.reset(name)

    def tearDown(self):
        for name in ("StudFit", "SocketFit"):
            self.preferences.reset(name)
        super().tearDown()

    def test_defaults_come_from_the_one_table(self):
        from core.parts.interfaces import Fit

        self.assertEqual(self.preferences.get("StudFit"), Fit.stud_fit)
        self.assertEqual(self.preferences.get("SocketFit"), Fit.socket_fit)
        body, _, _ = padded_body(self.doc)
        f = fab().make_fabrication(body)
        self.assertAlmostEqual(f.StudFit.Value, Fit.stud_fit)
        self.assertAlmostEqual(f.SocketFit.Value, Fit.socket_fit)
        self.assertNotIn("Clearance", f.PropertiesList)
        self.preferences.set("StudFit", 0.12)
        self.preferences.set("SocketFit", -0.04)
        g = fab().make_fabrication(body)
        self.assertAlmostEqual(g.StudFit.Value, 0.12)
        self.assertAlmostEqual(g.SocketFit.Value, -0.04)
        self.assertAlmostEqual(f.StudFit.Value, Fit.stud_fit)  # each keeps its own
        h = fab().make_fabrication(body, stud_fit=0.2, socket_fit=0.1)
        self.assertEqual((h.StudFit.Value, h.SocketFit.Value), (0.2, 0.1))

    def test_the_fits_make_the_printed_studs_and_sockets(self):
        # a 24 x 24 x 9.6 block, its middle cell of the middle layer printed: LEGO above
        # and below, so the part has one stud on top and one socket underneath
        source = self.doc.addObject("Part::Box", "Block")
        source.Length = source.Width = 24.0
        source.Height = 9.6
        self.doc.recompute()
        f = fab().make_fabrication(source, stud_fit=0.15, socket_fit=-0.05)
        fab().mark_high_res(f, box=(8.5, 8.5, 3.5, 15.5, 15.5, 6.0))
        self.doc.recompute()
        self.assertTrue(f.Status.startswith("ok"), f.Status)
        part = fab().printed_parts(f)[0]
        z0 = part.Shape.BoundBox.ZMin
        self.assertEqual(stud_diameters(part.Shape), [4.95])
        self.assertEqual(socket_widths(part.Shape, z0 + 1.0), [(4.75, 4.75)])
        f.StudFit, f.SocketFit = 0.0, 0.1
        self.doc.recompute()
        part = fab().printed_parts(f)[0]
        self.assertEqual(stud_diameters(part.Shape), [4.8])
        self.assertEqual(socket_widths(part.Shape, z0 + 1.0), [(4.9, 4.9)])

    def test_a_fit_out_of_range_fails_and_is_put_back(self):
        body, _, _ = padded_body(self.doc)
        f = fab().make_fabrication(body)
        self.doc.recompute()
        layout = f.LayoutJson
        f.StudFit = 0.95
        self.doc.recompute()
        self.assertTrue(f.Status.startswith("failed"), f.Status)
        self.assertIn("stud-fit", f.Status)
        self.assertAlmostEqual(f.StudFit.Value, 0.05)
        self.assertEqual(f.LayoutJson, layout)

    def test_an_old_document_with_a_clearance_opens_and_recomputes(self):
        from core.parts.interfaces import Fit

        body, _, _ = padded_body(self.doc)
        f = fab().make_fabrication(body)
        fab().mark_high_res(f, box=(0, 0, 12.8, 8, 8, 19.2))
        self.doc.recompute()
        # what an older version saved: a Clearance (a diameter), no StudFit/SocketFit,
        # and its parameters with the Clearance in LastGood
        for name in ("StudFit", "SocketFit"):
            f.removeProperty(name)
        f.addProperty("App::PropertyLength", "Clearance", "Fabrication", "FDM clearance")
        f.Clearance = 0.1
        last = json.loads(f.LastGood)
        last["parameters"] = {k: v for k, v in last["parameters"].items()
                              if k not in ("StudFit", "SocketFit")} | {"Clearance": 0.1}
        f.LastGood = json.dumps(last)
        layout = f.LayoutJson
        path = self.path("old.FCStd")
        self.doc.saveAs(path)
        App.closeDocument(self.doc.Name)
        self.doc = App.openDocument(path)
        f = fab().fabrications(self.doc)[0]
        self.assertNotIn("Clearance", f.PropertiesList)
        self.assertAlmostEqual(f.StudFit.Value, Fit.stud_fit)
        self.assertAlmostEqual(f.SocketFit.Value, Fit.socket_fit)
        self.assertEqual(f.LayoutJson, layout)
        f.Proxy.onDocumentRestored(f)  # idempotent
        self.assertEqual(f.PropertiesList.count("StudFit"), 1)
        f.BrickSet = "3001"  # fails: the parameters go back, the Clearance entry is ignored
        self.doc.recompute()
        self.assertTrue(f.Status.startswith("failed"), f.Status)
        self.assertEqual(f.BrickSet, "all")
        self.assertTrue(fab().recompute(f), f.Status)
        self.assertEqual(len(fab().printed_parts(f)), 1)
        self.assertNotIn("Clearance", json.loads(f.LastGood)["parameters"])

    def test_calibration_strip_around_the_preferences(self):
        import trimesh

        self.preferences.set("StudFit", 0.2)
        out = Path(self.path("strip"))
        strip = fab().make_calibration_strip(out, self.doc)
        # 0.10 under the smaller fit (0.0) to 0.15 over the larger (0.2), steps of 0.05
        expected = [-0.10, -0.05, 0.0, 0.05, 0.10, 0.15, 0.20, 0.25, 0.30, 0.35]
        self.assertEqual([round(v, 6) for v in strip.Values], expected)
        self.assertEqual(strip.PrintFile, str(out / "calibration_strip.stl"))
        for name in ("calibration_strip.stl", "calibration_strip.3mf", "README.txt"):
            self.assertGreater((out / name).stat().st_size, 0)
        self.assertTrue(strip.Shape.isValid())
        self.assertEqual(len(strip.Shape.Solids), 1)
        self.assertEqual(stud_diameters(strip.Shape), [round(4.8 + v, 6) for v in expected])
        widths = socket_widths(strip.Shape, 1.0)
        self.assertEqual(widths, [(round(4.8 + v, 6),) * 2 for v in expected])
        mesh = trimesh.load(out / "calibration_strip.stl", force="mesh")
        self.assertAlmostEqual(mesh.volume, strip.Shape.Volume, delta=1e-3 * strip.Shape.Volume)
        self.assertIn(strip, self.doc.Objects)

    def test_calibration_strip_into_a_file_adds_nothing(self):
        from core.errors import InputError

        blocker = Path(self.path("a_file"))
        blocker.write_text("")
        with self.assertRaises(InputError):
            fab().make_calibration_strip(blocker, self.doc)
        self.assertEqual(self.doc.Objects, [])


class TestExamples(FabrickatorTestCase):
    """The bundled HMD example and a model from the shared set, end to end."""

    def test_hmd_example_with_two_printed_lens_mounts(self):
        import Part

        sys.path.insert(0, str(ROOT / "examples"))
        try:
            import hmd
        finally:
            sys.path.remove(str(ROOT / "examples"))
        step = self.path("hmd.step")
        hmd.build_hmd().val().exportStep(step)
        source = self.doc.addObject("Part::Feature", "HMD")
        source.Shape = Part.read(step)
        f = fab().make_fabrication(source)
        for box in HMD_LENS_MOUNTS:
            fab().mark_high_res(f, box=box)
        self.doc.recompute()
        self.assertTrue(f.Status.startswith("ok"), f.Status)
        self.assertGreater(f.Bricks, 100)
        parts = fab().printed_parts(f)
        self.assertEqual([p.PartId for p in parts], ["P1", "P2"])
        for p in parts:
            self.assertTrue(p.Shape.isValid())
            self.assertTrue(p.Engraved)
        self.assertEqual(len(covered_cells(f)), f.Plates)

    def test_model_file_from_the_shared_set(self):
        if not MODELS.is_dir():
            self.skipTest(f"{MODELS} is absent: the shared benchmark models are not here")
        source, f = fab().legofy_file(MODELS / "xyz_calibration_cube.stl", self.doc)
        self.assertEqual(source.TypeId, "Mesh::Feature")
        self.doc.recompute()
        self.assertTrue(f.Status.startswith("ok"), f.Status)
        self.assertEqual(len(covered_cells(f)), f.Plates)
        from core.errors import InputError
        with self.assertRaises(InputError):
            fab().import_model(MODELS / "broken_triangle_soup.stl", self.doc)


# The parity tests (the command line and the workbench give the same result) run with these.
from TestFabrickatorParity import TestLikeFreeCAD, TestParity  # noqa: E402,F401
from TestFabrickatorUndo import TestUndo  # noqa: E402,F401
from TestFabrickatorLookApp import TestLookApp  # noqa: E402,F401
# The Addon Manager's install in a clean FreeCAD user folder runs with these.
from TestFabrickatorInstall import TestAddonManagerInstall, TestInstallWithoutNetwork  # noqa: E402,F401
# The force check's Loads, Ground and Clutch (issue 14), and its parity with the command line.
from TestFabrickatorForces import TestForceParity, TestLoads  # noqa: E402,F401
# Suggest high-res regions (issue 48): one region per suggestion, as the command line finds them.
from TestFabrickatorSuggest import TestSuggest  # noqa: E402,F401
