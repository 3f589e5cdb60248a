"""Fabrickator from Python: everything the toolbar does, as documented calls.

A macro or a test drives the workbench with these functions, in
``freecadcmd`` as in the GUI (view providers are attached only when the GUI
is up)::

    import FabrickatorWorkbench as fab
    f = fab.make_fabrication(doc.Body)              # a solid, or a mesh feature
    fab.mark_high_res(f, box=(-54, 25, 25.5, -9, 36, 70.5))
    doc.recompute()                                 # runs the core
    fab.make_load(doc, f, (-40, 40, 88, 40, 80, 92), 170)   # a phone on top (g)
    doc.recompute()
    fab.export(f, "/tmp/parts")                     # STL, STEP, 3MF, instructions
    fab.report(f)["speedup"]

Like FreeCAD's own ``make_*`` functions they change the document but do not
recompute it (call ``doc.recompute()``), and do not open transactions (the
commands do that around them).
"""

from __future__ import annotations

import json
import math
import shutil
import tempfile
from pathlib import Path

import FreeCAD as App
import Mesh
import Part

from core.errors import InputError
from core.instructions import bom as core_bom
from core.parts import calibration
from core.watch import model_name, same_model
from FabrickatorWorkbench import bridge, deps, log, preferences
from FabrickatorWorkbench.objects import tree
from FabrickatorWorkbench.objects.fabricate import edits
from FabrickatorWorkbench.objects.fabrication import Fabrication, is_fabrication
from FabrickatorWorkbench.objects.high_res_region import HighResRegion
from FabrickatorWorkbench.objects.high_res_region import boxes as region_boxes
from FabrickatorWorkbench.objects.load import Load
from FabrickatorWorkbench.viewproviders import attach_missing

#: Model formats Legofy reads from a file: B-rep ones become Part features,
#: meshes (loaded and repaired by the core) Mesh features.
BREP_SUFFIXES = (".step", ".stp", ".brep", ".brp", ".iges", ".igs")
MESH_SUFFIXES = (".stl", ".obj", ".ply", ".3mf", ".fcstd")

#: Property of an imported object naming the file it came from (:func:`import_model`).
MODEL_FILE = "ModelFile"

#: A brick's box is shrunk by this much (mm) on every side when it becomes a
#: high-res box, so that it never touches a neighbouring cell.
BOX_INSET_MM = 1e-3


def _require(what: str) -> None:
    """Raise ImportError (after one Report-view line) when the core cannot be used."""
    if not deps.check(what):
        raise ImportError(f"Fabrickator cannot run {what}: see the Report view")


def make_fabrication(source, doc=None, brick_set: str | None = None,
                     stud_fit: float | None = None, socket_fit: float | None = None,
                     seed: int = 0, scale: float = 1.0,
                     seconds_per_brick: float | None = None, slice_print_times: bool | None = None,
                     label: str | None = None):
    """A new Fabrication of ``source`` (an object with a solid, or a Mesh feature).

    The Source is hidden, as FreeCAD's own features hide their inputs (deleting
    the Fabrication shows it again).  Unset parameters come from the preferences
    (``stud_fit``/``socket_fit``, mm,
    signed: see :class:`core.parts.interfaces.Fit`).  The result appears after
    the next ``doc.recompute()``.  Raises ValueError when ``source`` has no
    solid and no mesh.
    """
    _require("make_fabrication")
    doc = doc or source.Document
    if bridge.source_kind(source) is None:
        raise ValueError(f"{source.Label} has no solid and no mesh to build from")
    obj = doc.addObject("App::FeaturePython", "Fabrication")
    Fabrication(obj)
    obj.Source = source
    obj.BrickSet = brick_set if brick_set is not None else preferences.get("BrickSet")
    obj.StudFit = float(stud_fit if stud_fit is not None else preferences.get("StudFit"))
    obj.SocketFit = float(socket_fit if socket_fit is not None else preferences.get("SocketFit"))
    obj.Seed = int(seed)
    obj.Scale = float(scale)
    obj.SecondsPerBrick = (seconds_per_brick if seconds_per_brick is not None
                           else preferences.get("SecondsPerBrick"))
    obj.SlicePrintTimes = (slice_print_times if slice_print_times is not None
                           else preferences.get("SliceOnRecompute"))
    obj.Label = label or f"{source.Label} LEGO"
    source.Visibility = False
    if App.GuiUp:
        attach_missing(obj)
    return obj


def fabrications(doc=None) -> list:
    """The Fabrications of ``doc`` (the active document by default)."""
    doc = doc or App.ActiveDocument
    return [o for o in doc.Objects if is_fabrication(o)] if doc else []


def fabrication_of(obj):
    """The Fabrication that ``obj`` (itself, a brick, group, printed part or region) belongs to."""
    seen = set()
    while obj is not None and obj.Name not in seen:
        if is_fabrication(obj):
            return obj
        seen.add(obj.Name)
        parents = [p for p in obj.InList if is_fabrication(p) or tree.role(p)]
        obj = parents[0] if parents else None
    return None


def mark_high_res(fab, box=None, boxes=(), solid=None, faces=None, bricks=(), label=None):
    """A new HighResRegion of ``fab``: what it touches is printed exactly.

    Give one of: ``box`` (X0, Y0, Z0, X1, Y1, Z1) or ``boxes`` (several) in
    the Source's mm; ``solid``, an object whose solid or mesh is the region;
    ``faces``, faces of the Source as ``[(obj, ["Face3", ...])]`` or
    ``(obj, "Face3")``; ``bricks``, brick objects or brick ids of the
    current layout (their boxes are stored, so the marks stay put when the
    layout changes).  Returns the region; recompute to apply it.
    """
    given = [box is not None or bool(boxes), solid is not None, faces is not None, bool(bricks)]
    if sum(given) != 1:
        raise ValueError("mark_high_res takes exactly one of box/boxes, solid, faces, bricks")
    doc = fab.Document
    region = doc.addObject("Part::FeaturePython", "HighResRegion")
    HighResRegion(region)
    if box is not None or boxes:
        region.Mode = "Bricks"
        region.Boxes = _flat_boxes(([box] if box is not None else []) + list(boxes))
    elif solid is not None:
        region.Mode = "Solid"
        region.RegionSolid = solid
    elif faces is not None:
        region.Mode = "Faces"
        region.Faces = _face_links(faces)
    else:
        region.Mode = "Bricks"
        region.Boxes = _flat_boxes(brick_boxes(fab, bricks))
    region.Label = label or f"High-res {region.Mode.lower()}"
    fab.Regions = list(fab.Regions) + [region]
    if App.GuiUp:
        attach_missing(region)
    region.Proxy.execute(region)
    fab.touch()
    return region


def make_load(doc, fab, where, grams: float, label: str | None = None):
    """A new Load of ``fab`` in ``doc``: ``grams`` resting on the bricks ``where`` touches.

    ``where`` is a box, a tuple (X0, Y0, Z0, X1, Y1, Z1) in the Source's mm; a
    ``Part.Shape`` or an object with one (its bounding box: a phone modelled
    in the document); or a list of brick objects or brick ids of the current
    layout (the box around them).  The Load is listed in the Fabrication's
    ``Loads`` and touches it; recompute to check the forces with it.  Raises
    ValueError for a mass not above 0 g or an empty box.
    """
    grams = float(grams)
    if not (math.isfinite(grams) and grams > 0):
        raise ValueError(f"a load's mass must be more than 0 g, not {grams!r}")
    lo, hi = _load_box(fab, where)
    if any(h - l <= 0 for l, h in zip(lo, hi)):
        raise ValueError(f"the load's box {list(lo)}..{list(hi)} is empty: each side must be "
                         f"longer than 0 mm")
    obj = doc.addObject("Part::FeaturePython", "Load")
    Load(obj)
    obj.Placement = App.Placement(App.Vector(*lo), App.Rotation())
    obj.Length, obj.Width, obj.Height = (h - l for l, h in zip(lo, hi))
    obj.Mass = grams
    obj.Label = label or f"Load {grams:g} g"
    fab.Loads = list(fab.Loads) + [obj]
    if App.GuiUp:
        attach_missing(obj)
    obj.Proxy.execute(obj)
    fab.touch()
    return obj


def _load_box(fab, where) -> tuple[tuple, tuple]:
    """(lo, hi) of the box ``where`` names (see :func:`make_load`), in the Source's mm."""
    shape = where if isinstance(where, Part.Shape) else getattr(where, "Shape", None)
    if shape is not None:
        if shape.isNull():
            raise ValueError("the load's shape is empty")
        b = shape.BoundBox
        return (b.XMin, b.YMin, b.ZMin), (b.XMax, b.YMax, b.ZMax)
    if isinstance(where, tuple):
        if len(where) != 6:
            raise ValueError(f"a load's box is six numbers X0,Y0,Z0,X1,Y1,Z1, not {where!r}")
        values = [float(v) for v in where]
        return (tuple(min(values[n], values[n + 3]) for n in range(3)),
                tuple(max(values[n], values[n + 3]) for n in range(3)))
    try:
        boxes = brick_boxes(fab, list(where))
    except (AttributeError, KeyError, TypeError, ValueError):
        raise ValueError(f"make_load: {where!r} are not bricks of {fab.Label}'s layout (a box "
                         f"is a tuple X0,Y0,Z0,X1,Y1,Z1)") from None
    if not boxes:
        raise ValueError("make_load needs a box, a shape or bricks")
    return (tuple(min(b[n] for b in boxes) for n in range(3)),
            tuple(max(b[n + 3] for b in boxes) for n in range(3)))


def loads(fab) -> list:
    """The Load objects of ``fab``."""
    return list(getattr(fab, "Loads", ()))


def unmark(fab, bricks) -> int:
    """Remove the brush marks (boxes of Bricks regions) that touch ``bricks``; returns how many.

    Regions left without boxes are deleted.  Recompute to apply.
    """
    targets = brick_boxes(fab, bricks)
    removed = 0
    for region in list(fab.Regions):
        if region.Mode != "Bricks":
            continue
        keep = [b for b in region_boxes(region) if not any(_overlap(b, t) for t in targets)]
        removed += len(region_boxes(region)) - len(keep)
        if not keep:
            fab.Regions = [r for r in fab.Regions if r.Name != region.Name]
            fab.Document.removeObject(region.Name)
        elif len(keep) != len(region_boxes(region)):
            region.Boxes = _flat_boxes(keep)
            region.Proxy.execute(region)
    if removed:
        fab.touch()
    return removed


def merge_bricks(fab, bricks) -> None:
    """Merge brush: the printed parts holding ``bricks`` (and those bricks) become one part."""
    _edit(fab, "merge", bricks)


def split_bricks(fab, bricks) -> None:
    """Split brush: each of ``bricks`` becomes a printed part of its own."""
    _edit(fab, "split", bricks)


def _edit(fab, op: str, bricks) -> None:
    changes = edits(fab) + [{"op": op, "boxes": brick_boxes(fab, bricks)}]
    fab.PartEdits = json.dumps(changes)
    fab.touch()


def brick_boxes(fab, bricks) -> list[list[float]]:
    """The boxes (Source mm, inset by BOX_INSET_MM) of brick objects or brick ids of ``fab``
    (:meth:`core.model.Grid.box_mm` of each brick in the stored layout's grid)."""
    stored = tree.stored_layout(fab)
    by_id = {b.id: b for b in stored.bricks}
    scale = float(fab.Scale) or 1.0
    out = []
    for b in bricks:
        brick = by_id[int(b) if isinstance(b, int) else int(b.BrickId)]
        lo, hi = stored.grid.box_mm(brick.cell, brick.size)
        out.append([float(v) / scale for v in list(lo + BOX_INSET_MM) + list(hi - BOX_INSET_MM)])
    return out


def _overlap(a, b) -> bool:
    return all(a[n] < b[n + 3] and b[n] < a[n + 3] for n in range(3))


def _flat_boxes(boxes) -> list[float]:
    out = []
    for b in boxes:
        values = [float(v) for v in b]
        if len(values) != 6:
            raise ValueError(f"a box is six numbers X0,Y0,Z0,X1,Y1,Z1, not {b!r}")
        lo = [min(values[n], values[n + 3]) for n in range(3)]
        hi = [max(values[n], values[n + 3]) for n in range(3)]
        out += lo + hi
    return out


def _face_links(faces) -> list:
    if isinstance(faces, tuple) and len(faces) == 2 and isinstance(faces[1], str):
        faces = [(faces[0], [faces[1]])]
    return [(obj, list(names) if not isinstance(names, str) else [names]) for obj, names in faces]


def bricks(fab) -> list:
    """The brick objects of ``fab``, layer by layer."""
    return tree.bricks(fab)


def ghosts(fab) -> list:
    """The removed bricks (ghosts) of ``fab``'s last recompute: links in the "Removed
    bricks" group, not bricks of the layout."""
    return tree.ghosts(fab)


def printed_parts(fab) -> list:
    """The PrintedPart objects of ``fab``."""
    return tree.printed_parts(fab)


def regions(fab) -> list:
    """The HighResRegion objects of ``fab``."""
    return list(fab.Regions)


def report(fab) -> dict:
    """The core's report (report.json) of the last successful recompute, with the steps."""
    doc = json.loads(fab.ReportJson) if fab.ReportJson else {}
    if fab.StepsJson:
        doc["assembly"] = json.loads(fab.StepsJson)
    return doc


def steps(fab) -> list[dict]:
    """The assembly steps: [{"number", "layer", "bricks" (ids), "printed_part", ...}]."""
    return json.loads(fab.StepsJson)["steps"] if fab.StepsJson else []


def step_notes(fab) -> tuple[dict[str, str], list[dict]]:
    """What the instructions say at each step (step number as text -> words) and the props
    (:attr:`core.instructions.build_order.BuildOrder.props`) of ``fab``'s last result; empty for a
    result stored before they were kept."""
    doc = json.loads(fab.StepsJson) if fab.StepsJson else {}
    return dict(doc.get("warnings", {})), list(doc.get("props", []))


def bom(fab) -> list:
    """The LEGO rows of the bill of materials of ``fab``'s stored layout, as ``bom.csv``
    gives them (:func:`core.instructions.bom.lines`): per design and colour the count and,
    with an inventory, how many are owned (``owned``; to buy: ``count - owned``)."""
    from core.inventory import colouring_of  # loads scipy

    _require("layout")
    colouring = colouring_of(json.loads(fab.LayoutJson))
    return core_bom.lines(tree.stored_layout(fab), colouring=colouring)


def layout(fab):
    """The stored layout as a :class:`core.model.Layout` (steps included); ValueError when
    ``fab`` has none yet."""
    _require("layout")
    return tree.stored_layout(fab)


def export(fab, folder) -> list[str]:
    """Write the last result of ``fab`` into ``folder`` exactly as the command line writes an
    output folder (:func:`core.pipeline.write_outputs`): the printed parts (``parts/``:
    STL, STEP, ``plate-1.3mf``), ``layout.json``, ``layout.png``, ``report.json``, the
    instructions, the iteration snapshot and, after an iteration, ``changes.html``.
    Returns the names written (top level).  Reads the document only.

    Raises ValueError when ``fab`` has not been computed, InputError when
    ``folder`` holds other files.
    """
    _require("export")
    from core import pipeline

    if not fab.LayoutJson or not fab.IterationState:
        raise ValueError(f"{fab.Label} has no result yet: recompute it first")
    doc = report(fab)
    doc.pop("assembly", None)
    with tempfile.TemporaryDirectory(prefix="fabrickator-export-") as work:
        shutil.unpack_archive(fab.IterationState, work, "zip")
        written = pipeline.write_outputs(pipeline.stored(work, doc), folder, report_doc=doc)
    log.message(f"{fab.Label}: exported {len(doc.get('printed_parts', ()))} printed part(s) and "
                f"the instructions to {folder}")
    return list(written["outputs"])


def remove_owned(fab) -> None:
    """Delete everything ``fab`` made (bricks, groups, printed parts) and show its Source
    again unless another Fabrication builds it; the regions stay.  What deleting a
    Fabrication in the tree does (delete ``fab`` itself afterwards)."""
    fab.Proxy.remove_owned(fab)


def clear_changes(fab) -> int:
    """Take away the marks of the last recompute: the highlighted (new) bricks get their
    LEGO colour, the ghosts of removed bricks go, ``Changes`` empties (the printed
    parts' ``Reprint`` stays: it says what to print).  Returns how many bricks were
    highlighted.  No recompute needed."""
    count = tree.clear_changes(fab)
    if fab.Changes:
        fab.Changes = []
        fab.purgeTouched()
    return count


def import_model(path, doc=None):
    """Add the model file at ``path`` to ``doc``: a Part feature (STEP, IGES, BREP) or a Mesh
    feature (STL, OBJ, PLY, 3MF, FCStd; loaded and repaired by the core).  Returns the object.

    Raises :class:`core.errors.InputError` for a file the core refuses.
    """
    _require("import")
    path = Path(path)
    doc = doc or App.ActiveDocument or App.newDocument(path.stem)
    suffix = path.suffix.lower()
    name = "".join(c if c.isalnum() else "_" for c in path.stem) or "Model"
    if suffix in BREP_SUFFIXES:
        if not path.is_file():
            raise InputError(f"{path}: no such file")
        obj = doc.addObject("Part::Feature", name)
        obj.Shape = Part.read(str(path))
    else:
        mesh = _mesh_of(path)
        obj = doc.addObject("Mesh::Feature", name)
        obj.Mesh = mesh
    obj.Label = path.stem
    obj.addProperty("App::PropertyString", MODEL_FILE, "Fabrickator",
                    "Model file this object was imported from (a new version of it updates it)")
    setattr(obj, MODEL_FILE, str(path.resolve()))
    obj.setEditorMode(MODEL_FILE, 1)
    return obj


def reload_model(obj, path) -> None:
    """Replace the geometry of ``obj`` (made by :func:`import_model`) by the model file at
    ``path``: a new version of the part.  Its Fabrications recompute as an iteration."""
    _require("import")
    path = Path(path)
    if obj.TypeId == "Mesh::Feature":
        obj.Mesh = _mesh_of(path)
    else:
        obj.Shape = Part.read(str(path))
    if hasattr(obj, MODEL_FILE):
        setattr(obj, MODEL_FILE, str(path.resolve()))
    obj.touch()


def imported_from(doc, path) -> list:
    """The objects of ``doc`` imported (:func:`import_model`) from a version of the model
    file ``path`` (:func:`core.watch.same_model`: the same folder and the same
    :func:`core.watch.model_name`, letter case aside), latest first."""
    path = Path(path).resolve()
    found = []
    for obj in doc.Objects:
        source = getattr(obj, MODEL_FILE, "")
        if source and same_model(source, path):
            found.append(obj)
    return found[::-1]


def feed_file(path, doc=None) -> tuple:
    """A model file as the next version of what it is a version of: when ``doc`` has a
    Fabrication of an object imported from the same model (same name, or a versioned
    name, :func:`core.watch.same_model`), that object takes the file's geometry and its
    Fabrications will recompute as an iteration; otherwise the file is legofied into a
    new Fabrication.  Returns (source, [fabrications], new); recompute to apply."""
    doc = doc or App.ActiveDocument or App.newDocument("Watched")
    for obj in imported_from(doc, path):
        fabs = [o for o in obj.InList if is_fabrication(o)]
        if fabs:
            reload_model(obj, path)
            for fab in fabs:
                fab.touch()
            return obj, fabs, False
    source, fab = legofy_file(path, doc)
    return source, [fab], True


def _mesh_of(path: Path):
    """The model file at ``path`` loaded and repaired by the core, as a FreeCAD mesh."""
    from core.io import meshes as mesh_io

    model = mesh_io.load_model(path)
    mesh = Mesh.Mesh()
    mesh.addFacets(model.mesh.triangles.tolist())
    for line in model.repaired:
        log.message(f"{path.name}: {line}")
    return mesh


def legofy_file(path, doc=None, **parameters):
    """Import the model file at ``path`` and make its Fabrication; returns (source, fabrication)."""
    source = import_model(path, doc)
    return source, make_fabrication(source, **parameters)


#: Value of the ``FabrickatorRole`` property of a calibration strip object.
CALIBRATION_ROLE = "CalibrationStrip"


def make_calibration_strip(folder, doc=None, values=None):
    """Write the calibration strip (:func:`core.parts.calibration.write_strip`) into ``folder``
    and show it in ``doc`` (the active document, or a new one); returns the new object.

    The strip is made around the preferences' stud and socket fit
    (:func:`core.parts.calibration.column_values`) unless ``values`` (mm) are given.
    The object is a Part feature with the strip's exact solid, its ``Values``
    and the file to print (``PrintFile``); the Report view says which file to
    print and where the instructions are.  Raises
    :class:`core.errors.InputError` (the files are not written, nothing is
    added) for a folder that cannot be written or values out of range.
    """
    _require("the calibration strip")
    fit = preferences.fit()
    if values is None:
        values = calibration.column_values(fit=fit)
    strip, written = calibration.write_strip(folder, values, fit)
    doc = doc or App.ActiveDocument or App.newDocument("CalibrationStrip")
    obj = doc.addObject("Part::Feature", "CalibrationStrip")
    obj.Shape = bridge.occ_to_part(strip.solid)
    obj.Label = "Calibration strip"
    for kind, name, tip in (
            ("App::PropertyString", "FabrickatorRole", "Fabrickator object role"),
            ("App::PropertyFloatList", "Values", "The columns' values left to right, mm: "
                                                 "stud 4.8 + value across, socket 4.8 + value wide"),
            ("App::PropertyFile", "PrintFile", "The STL to print (README.txt beside it says how "
                                               "to read the strip)")):
        obj.addProperty(kind, name, "Calibration", tip)
    obj.FabrickatorRole = CALIBRATION_ROLE
    obj.Values = [float(v) for v in values]
    obj.PrintFile = str(written[0])
    for name in ("FabrickatorRole", "Values", "PrintFile"):
        obj.setEditorMode(name, 2 if name == "FabrickatorRole" else 1)
    first, last = calibration.label(values[0]), calibration.label(values[-1])
    log.message(f"calibration strip of {len(values)} columns ({first} .. {last} mm): print "
                f"{written[0]} (or {written[1].name}) as it lies, no supports; {written[2]} "
                f"says how to read it (then set Stud fit and Socket fit in the preferences)")
    return obj


def recompute(fab) -> bool:
    """Recompute the document of ``fab``; True when ``fab`` computed without error."""
    fab.touch()
    fab.Document.recompute()
    return fab.Status.startswith("ok")


__all__ = ["make_fabrication", "fabrications", "fabrication_of", "mark_high_res", "unmark",
           "make_load", "loads",
           "merge_bricks", "split_bricks", "brick_boxes", "bricks", "printed_parts", "regions",
           "report", "steps", "layout", "export", "remove_owned",
           "import_model", "reload_model", "legofy_file", "recompute", "clear_changes", "ghosts",
           "feed_file", "model_name", "make_calibration_strip"]
