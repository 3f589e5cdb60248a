"""The tree under a Fabrication: one object per brick, grouped by layer, and its printed parts.

Every brick is an ``App::Link`` to the prototype of its part and colour
(:mod:`.prototype`), placed at its cell, with the properties PartNumber,
Cell, Size, Layer, Kind, Step, PrintedPart, BrickId and Changed (group
"Brick").  Bricks sit in one ``App::DocumentObjectGroup`` per plate layer;
printed parts in a "Printed parts" group, regions in a "High-res regions"
group, loads (if any) in a "Loads" group, all inside the Fabrication.

:func:`sync` brings the tree in line with a new core result and keeps every
brick object whose brick is still in the layout (after a design iteration:
the same brick id, :mod:`core.iterate` keeps ids stable; otherwise the same
part, cell, size and kind), so a recompute that changes little changes few
objects.  What the recompute changed stays visible until the next one:

* new bricks (``Changed``) link to the prototype of their part in
  :data:`HIGHLIGHT_COLOUR`, so they stand out in the 3D view (in a document
  made without the GUI too); the next recompute that does not change them
  gives them their LEGO colour back, and :func:`clear_changes` does at once;
* bricks taken off are *ghosts*: one ``App::Link`` each (role
  ``RemovedBrick``, the prototype the brick had, where the brick was) in a
  "Removed bricks" group, drawn grey and transparent in the GUI
  (:func:`FabrickatorWorkbench.viewproviders.brick.apply_ghost_look`).  They
  are not bricks of the layout (:func:`bricks` leaves them out) and the next
  recompute replaces them.
"""

from __future__ import annotations

import json
from collections import defaultdict

import FreeCAD as App

from core.catalog import BY_NUMBER
from core.colours import brick_colours, palette_codes, rgb as code_rgb
from core.model import Grid, Layout
from FabrickatorWorkbench import bridge, preferences
from FabrickatorWorkbench.objects import prototype as prototypes_module
from FabrickatorWorkbench.objects.printed_part import PrintedPart
from FabrickatorWorkbench.objects.properties import HIDDEN, READ_ONLY, Prop, ensure
from FabrickatorWorkbench.objects.prototype import (HIGHLIGHT_COLOUR, hide_link_properties,
                                                    make_prototype, rgb_key)
from FabrickatorWorkbench.viewproviders import attach_missing
from FabrickatorWorkbench.viewproviders.brick import apply_ghost_look

QT = App.Qt.QT_TRANSLATE_NOOP

BRICK_ROLE = "Brick"
LAYER_ROLE = "Layer"
PRINTED_GROUP_ROLE = "PrintedParts"
REGIONS_GROUP_ROLE = "Regions"
LOADS_GROUP_ROLE = "Loads"
PROTOTYPES_ROLE = "Prototypes"
GHOST_ROLE = "RemovedBrick"
GHOSTS_GROUP_ROLE = "RemovedBricks"

#: Property group of a brick's own properties.  FreeCAD's property view orders groups
#: by name (PropertyModel::buildUp, 0.20 and 1.x), and App::Link's ~11 properties are
#: in " Link": the leading space puts this group above them.
BRICK_GROUP = " Brick"

BRICK_PROPERTIES = (
    Prop("App::PropertyString", "FabrickatorRole", "Base", QT("App::Property", "Fabrickator object role"),
         BRICK_ROLE, HIDDEN),
    Prop("App::PropertyString", "PartNumber", BRICK_GROUP,
         QT("App::Property", "LEGO design number")),
    Prop("App::PropertyIntegerList", "Cell", BRICK_GROUP,
         QT("App::Property", "Min cell (i, j, k) in the grid")),
    Prop("App::PropertyIntegerList", "Size", BRICK_GROUP,
         QT("App::Property", "Extent in cells along x, y, z")),
    Prop("App::PropertyInteger", "Layer", BRICK_GROUP,
         QT("App::Property", "Lowest plate layer (k)")),
    Prop("App::PropertyString", "Kind", BRICK_GROUP,
         QT("App::Property", "lego, or printed (part of a printed part)")),
    Prop("App::PropertyInteger", "Step", BRICK_GROUP,
         QT("App::Property", "Assembly step that places the brick")),
    Prop("App::PropertyString", "PrintedPart", BRICK_GROUP,
         QT("App::Property", "ID of the printed part the brick belongs to, if printed")),
    Prop("App::PropertyInteger", "BrickId", BRICK_GROUP,
         QT("App::Property", "Brick id in the layout")),
    Prop("App::PropertyBool", "Changed", BRICK_GROUP,
         QT("App::Property", "New or changed in the last recompute")),
)


GHOST_PROPERTIES = (
    Prop("App::PropertyString", "FabrickatorRole", "Base", QT("App::Property", "Fabrickator object role"),
         GHOST_ROLE, HIDDEN),
    Prop("App::PropertyString", "PartNumber", "Removed brick",
         QT("App::Property", "LEGO design number"), "", READ_ONLY),
    Prop("App::PropertyIntegerList", "Cell", "Removed brick",
         QT("App::Property", "Min cell (i, j, k) the brick took, in the current grid"), None,
         READ_ONLY),
    Prop("App::PropertyIntegerList", "Size", "Removed brick",
         QT("App::Property", "Extent in cells along x, y, z"), None, READ_ONLY),
    Prop("App::PropertyString", "Kind", "Removed brick",
         QT("App::Property", "lego, or printed (part of a printed part)"), "", READ_ONLY),
    Prop("App::PropertyString", "PrintedPart", "Removed brick",
         QT("App::Property", "ID of the printed part the brick belonged to, if printed"), "",
         READ_ONLY),
    Prop("App::PropertyInteger", "BrickId", "Removed brick",
         QT("App::Property", "Id the brick had in the previous layout"), 0, READ_ONLY),
)


def role(obj) -> str | None:
    """The Fabrickator role of an object (None for other objects)."""
    return getattr(obj, "FabrickatorRole", None)


def child_groups(fab, wanted: str) -> list:
    """The Fabrication's direct child groups of role ``wanted``."""
    return [g for g in fab.Contents if role(g) == wanted]


def layer_groups(fab) -> list:
    """The layer groups, lowest layer first."""
    return sorted(child_groups(fab, LAYER_ROLE), key=lambda g: g.Layer)


def bricks(fab) -> list:
    """Every brick object of a Fabrication, layer by layer."""
    return [b for g in layer_groups(fab) for b in g.Group if role(b) == BRICK_ROLE]


def restore_bricks(fab) -> None:
    """Bring the brick objects of a document saved by an older version up to date: their
    properties in today's group (first in the property view), the Link properties a
    brick user never needs hidden."""
    for obj in bricks(fab):
        ensure(obj, BRICK_PROPERTIES)
        hide_link_properties(obj)


def ghosts(fab) -> list:
    """The removed bricks (ghosts) the last recompute took off."""
    return [g for grp in child_groups(fab, GHOSTS_GROUP_ROLE) for g in grp.Group
            if role(g) == GHOST_ROLE]


def printed_parts(fab) -> list:
    """The PrintedPart objects of a Fabrication, by ID."""
    return [p for g in child_groups(fab, PRINTED_GROUP_ROLE) for p in g.Group
            if role(p) == "PrintedPart"]


def prototypes(doc) -> list:
    """The brick prototypes of ``doc``."""
    return [o for g in doc.Objects if role(g) == PROTOTYPES_ROLE for o in g.Group]


def owned(fab) -> list:
    """Every object the Fabrication made (groups, bricks, ghosts, printed parts), children first."""
    out = []
    for g in fab.Contents:
        if role(g) in (LAYER_ROLE, PRINTED_GROUP_ROLE, GHOSTS_GROUP_ROLE):
            out += [c for c in g.Group if role(c) in (BRICK_ROLE, "PrintedPart", GHOST_ROLE)]
        if role(g) in (LAYER_ROLE, PRINTED_GROUP_ROLE, REGIONS_GROUP_ROLE, LOADS_GROUP_ROLE,
                       GHOSTS_GROUP_ROLE):
            out.append(g)
    return out


def remove_owned(fab) -> None:
    """Delete everything ``fab`` made (bricks, ghosts, layer groups, printed parts, the
    region and load groups); the regions and loads themselves and the Source stay,
    prototypes no other object uses go."""
    doc = fab.Document
    for obj in owned(fab):
        if role(obj) in (REGIONS_GROUP_ROLE, LOADS_GROUP_ROLE):
            obj.Group = []
        if doc.getObject(obj.Name) is not None:
            doc.removeObject(obj.Name)
    _remove_unused_prototypes(doc)


def _remove_unused_prototypes(doc) -> None:
    group = next((o for o in doc.Objects if role(o) == PROTOTYPES_ROLE), None)
    if group is None:
        return
    for proto in list(group.Group):
        if not [o for o in proto.InList if o.Name != group.Name]:
            doc.removeObject(proto.Name)
    if not group.Group:
        doc.removeObject(group.Name)


def stored_layout(fab) -> Layout:
    """The layout stored in Fabrication ``fab`` (its ``LayoutJson``) as a
    :class:`core.model.Layout`, steps included; ValueError when it has none yet."""
    if not fab.LayoutJson:
        raise ValueError(f"{fab.Label} has no layout yet: recompute it")
    return Layout.from_json(json.loads(fab.LayoutJson))


def placement(brick, grid: Grid) -> App.Placement:
    """Where the prototype of ``brick``'s part goes so that it fills the brick's cells
    of ``grid``.

    Prototypes have their short side along x; a brick whose x extent is
    the long side is the prototype turned 90 degrees about z.
    """
    lo, hi = grid.box_mm(brick.cell, brick.size)
    turned = brick.size[0] != BY_NUMBER[brick.part].footprint[0]
    if turned:
        return App.Placement(bridge.vector((hi[0], lo[1], lo[2])),
                             App.Rotation(App.Vector(0, 0, 1), 90))
    return App.Placement(bridge.vector(lo), App.Rotation())


def sync(fab, result) -> tuple[int, int]:
    """Make the tree under ``fab`` show ``result``; returns (bricks kept, bricks new or changed).

    When only the Source changed (``result.marks``), new bricks are
    highlighted and the bricks taken off become the ghosts of the "Removed
    bricks" group; otherwise (the first layout, or new parameters, regions or
    brush edits) nothing is marked.  Either way the previous marks go.
    """
    doc = fab.Document
    layout = result.fab.layout
    palette = preferences.palette()
    colours = brick_colours(layout, palette, layout.labels(),
                            getattr(result.fab, "colouring", None))
    shown = {rgb_key(code_rgb(code)) for code in palette_codes(palette)}
    had_layout = bool(fab.LayoutJson) and getattr(result, "marks", True)
    by_id = result.report.get("changes") is not None
    existing = {}
    for obj in bricks(fab):
        existing.setdefault(_brick_key(obj, by_id), obj)
    made = []
    protos = Prototypes(doc)
    by_layer: dict[int, list] = defaultdict(list)
    kept = changed = 0
    for brick, rgb in zip(layout.bricks, colours):
        obj = existing.pop(_key(brick.part, brick.cell, brick.size, brick.kind, brick.id, by_id),
                           None)
        new = obj is None
        if new:
            obj = doc.addObject("App::Link", _unused_name(fab, "Brick"))
            ensure(obj, BRICK_PROPERTIES)
            made.append(obj)
            changed += 1
        else:
            kept += 1
        highlight = had_layout and new
        proto = (protos.get(brick.part, HIGHLIGHT_COLOUR) if highlight
                 else _lego_prototype(obj, brick, protos, tuple(float(c) for c in rgb), shown))
        _update_brick(obj, brick, proto, placement(brick, layout.grid), changed=highlight)
        hide_link_properties(obj)
        by_layer[brick.cell[2]].append(obj)
    removed = list(existing.values())
    ghost_group = _sync_ghosts(fab, removed if had_layout else [], layout.grid, made)
    for obj in removed:
        doc.removeObject(obj.Name)
    layers = _sync_layers(fab, by_layer, made, layout.grid)
    printed_group = _group(fab, PRINTED_GROUP_ROLE, "Printed parts", made)
    printed_group.Group = _sync_printed(fab, printed_group, result, made)
    regions_group = _group(fab, REGIONS_GROUP_ROLE, "High-res regions", made)
    regions_group.Group = list(fab.Regions)
    loads_group = _sync_loads(fab, made)
    fab.Contents = ([regions_group] + ([loads_group] if loads_group else []) + [printed_group]
                    + ([ghost_group] if ghost_group else []) + layers)
    made += protos.made
    for obj in made + owned(fab) + protos.touched():
        if "Touched" in obj.State:
            obj.purgeTouched()
    if App.GuiUp:
        for obj in made:
            attach_missing(obj)
        for proto in protos.made:
            if role(proto) == prototypes_module.ROLE:
                prototypes_module.apply_colour(proto)
        for ghost in ghosts(fab):
            apply_ghost_look(ghost)
    return kept, changed


def utilisations(fab) -> list[tuple] | None:
    """(object, utilisation) for every LEGO brick and printed part of ``fab`` from its
    report's ``stability.force`` (unsupported: ``inf``; not covered: None; a printed part
    the largest of its bricks'); None when the report has no force check."""
    force = json.loads(fab.ReportJson).get("stability", {}).get("force") if fab.ReportJson else None
    if not force:
        return None
    values = force.get("utilisation", {})

    def of(brick_id: int):
        key = str(int(brick_id))
        if key not in values:
            return None
        return float("inf") if values[key] is None else float(values[key])

    out = [(b, of(b.BrickId)) for b in bricks(fab) if b.Kind != "printed"]
    for part in printed_parts(fab):
        known = [u for u in (of(i) for i in part.BrickIds) if u is not None]
        out.append((part, max(known) if known else None))
    return out


def clear_changes(fab) -> int:
    """Take the marks of the last recompute away: highlighted bricks get their LEGO
    colour back and the ghosts go.  Returns how many bricks were highlighted."""
    marked = [b for b in bricks(fab) if b.Changed]
    protos_touched = []
    if marked:
        layout = stored_layout(fab)
        from core.inventory import colouring_of  # loads scipy

        own = colouring_of(json.loads(fab.LayoutJson))
        rgb = {b.id: tuple(float(c) for c in colour)
               for b, colour in zip(layout.bricks, brick_colours(layout, preferences.palette(),
                                                                 layout.labels(), own))}
        protos = Prototypes(fab.Document)
        for obj in marked:
            obj.Changed = False
            obj.LinkedObject = protos.get(obj.PartNumber, rgb.get(obj.BrickId, HIGHLIGHT_COLOUR))
        if App.GuiUp:
            for proto in protos.made:
                if role(proto) == prototypes_module.ROLE:
                    prototypes_module.apply_colour(proto)
        protos_touched = protos.made + protos.touched()
    _sync_ghosts(fab, [], None, [])
    for obj in [fab] + marked + protos_touched:
        if "Touched" in obj.State:
            obj.purgeTouched()
    return len(marked)


def _unused_name(fab, base: str) -> str:
    """An object name for a new brick of ``fab`` that no object of the document has ever
    had: ``<base>_<n>`` with ``fab``'s ``NameSerial`` counted up.

    FreeCAD's recompute deletes, once the recompute ends, an object created in
    it under the name of an object deleted in an earlier recompute (the first
    new brick of an iteration that followed a fresh layout vanished that way);
    names never used before avoid it.
    """
    doc = fab.Document
    while True:
        fab.NameSerial = fab.NameSerial + 1
        name = f"{base}_{fab.Name}_{fab.NameSerial}"
        if doc.getObject(name) is None:
            return name


def _brick_key(obj, by_id: bool):
    """The key of a brick object: its id (iterations keep ids) or what it is and where."""
    return _key(obj.PartNumber, obj.Cell, obj.Size, obj.Kind, obj.BrickId, by_id)


def _key(part, cell, size, kind, brick_id=0, by_id: bool = False):
    if by_id:
        return int(brick_id)
    return (str(part), tuple(int(c) for c in cell), tuple(int(s) for s in size), str(kind))


def _lego_prototype(obj, brick, protos, rgb: tuple, shown: set):
    """The prototype a kept or new brick links to: a kept LEGO brick keeps its colour
    when it is one the palette draws (``shown``: rgb keys; so unchanged bricks look the
    same after a recompute), else the layout's colour (a palette change applies)."""
    linked = obj.LinkedObject if obj.TypeId == "App::Link" else None
    if (brick.kind == "lego" and linked is not None and role(linked) == "Prototype"
            and linked.PartNumber == brick.part and obj.Kind == "lego"
            and rgb_key(linked.Color) in shown):
        return linked
    return protos.get(brick.part, rgb)


def _sync_ghosts(fab, removed: list, grid: Grid | None, made: list):
    """Replace the ghosts of ``fab`` by ghosts of the brick objects ``removed`` (their
    cells in the stored layout's grid expressed in the new ``grid``); the group, or None
    when there are no ghosts (an empty group is deleted)."""
    doc = fab.Document
    groups = child_groups(fab, GHOSTS_GROUP_ROLE)
    for group in groups:
        old = [g for g in group.Group if role(g) == GHOST_ROLE]
        group.Group = []
        for ghost in old:
            doc.removeObject(ghost.Name)
    if not removed:
        if groups:
            fab.Contents = [g for g in fab.Contents if role(g) != GHOSTS_GROUP_ROLE]
        for group in groups:
            doc.removeObject(group.Name)
        return None
    group = groups[0] if groups else new_group(doc, "RemovedBricks", GHOSTS_GROUP_ROLE,
                                               "Removed bricks")
    if not groups:
        made.append(group)
    old_grid = stored_layout(fab).grid
    out = []
    for brick in removed:
        ghost = doc.addObject("App::Link", "RemovedBrick")
        ensure(ghost, GHOST_PROPERTIES)
        ghost.LinkedObject = brick.LinkedObject
        ghost.Placement = brick.Placement
        at = grid.nearest_cell(old_grid.corner_mm(tuple(brick.Cell)))
        ghost.PartNumber, ghost.Cell, ghost.Size = brick.PartNumber, list(at), list(brick.Size)
        ghost.Kind, ghost.PrintedPart, ghost.BrickId = brick.Kind, brick.PrintedPart, brick.BrickId
        ghost.Label = f"{brick.PartNumber} ({at[0]},{at[1]},{at[2]}) removed"
        ghost.Visibility = True
        made.append(ghost)
        out.append(ghost)
    group.Group = out
    return group


def _update_brick(obj, brick, proto, where: App.Placement, changed: bool) -> None:
    """Set the brick object's link, placement and properties (only those that differ)."""
    values = {"PartNumber": brick.part, "Cell": list(brick.cell), "Size": list(brick.size),
              "Layer": int(brick.cell[2]), "Kind": brick.kind,
              "Step": int(brick.step) if brick.step is not None else 0,
              "PrintedPart": brick.printed_part or "", "BrickId": int(brick.id),
              "Changed": bool(changed)}
    for name, value in values.items():
        if getattr(obj, name) != value:
            setattr(obj, name, value)
    if obj.LinkedObject != proto:
        obj.LinkedObject = proto
    if not _same_placement(obj.Placement, where):
        obj.Placement = where
    label = f"{brick.part} ({brick.cell[0]},{brick.cell[1]},{brick.cell[2]})"
    if brick.kind == "printed":
        label += f" {brick.printed_part}"
    if obj.Label != label:
        obj.Label = label
    visible = brick.kind != "printed"
    if obj.Visibility != visible:
        obj.Visibility = visible


def _same_placement(a: App.Placement, b: App.Placement, tol: float = 1e-9) -> bool:
    """Whether two placements are equal to ``tol`` (position and quaternion)."""
    values = zip(tuple(a.Base) + tuple(a.Rotation.Q), tuple(b.Base) + tuple(b.Rotation.Q))
    return all(abs(x - y) <= tol for x, y in values)


def _sync_loads(fab, made: list):
    """The "Loads" group holding the Fabrication's Loads (made if missing), or None (the
    group removed) when it has none."""
    loads = list(getattr(fab, "Loads", ()))
    if not loads:
        for group in child_groups(fab, LOADS_GROUP_ROLE):
            group.Group = []
            fab.Document.removeObject(group.Name)
        return None
    group = _group(fab, LOADS_GROUP_ROLE, "Loads", made)
    if list(group.Group) != loads:
        group.Group = loads
    return group


def _group(fab, wanted: str, label: str, made: list):
    """The Fabrication's child group of role ``wanted``, made if missing."""
    found = child_groups(fab, wanted)
    if found:
        return found[0]
    group = new_group(fab.Document, "Group", wanted, label)
    made.append(group)
    return group


def new_group(doc, name: str, wanted: str, label: str):
    """A new ``App::DocumentObjectGroup`` with the Fabrickator role ``wanted``."""
    group = doc.addObject("App::DocumentObjectGroup", name)
    group.addProperty("App::PropertyString", "FabrickatorRole", "Base", "Fabrickator object role")
    group.FabrickatorRole = wanted
    group.setEditorMode("FabrickatorRole", HIDDEN)
    group.Label = label
    return group


def _sync_layers(fab, by_layer: dict, made: list, grid: Grid) -> list:
    """One group per occupied layer holding its bricks (labelled with the layer's
    bottom z in ``grid``); empty layer groups removed."""
    groups = {g.Layer: g for g in layer_groups(fab)}
    # a brick that moves to another layer must leave its old group before it joins the new
    # one (FreeCAD: "Object can only be in a single Group"), so changed groups empty first
    for k, group in groups.items():
        if list(group.Group) != by_layer.get(k, []):
            group.Group = []
    out = []
    for k in sorted(by_layer):
        group = groups.pop(k, None)
        if group is None:
            group = new_group(fab.Document, "Layer", LAYER_ROLE, f"Layer {k + 1}")
            group.addProperty("App::PropertyInteger", "Layer", "Layer", "Plate layer (k)")
            group.Layer = k
            group.setEditorMode("Layer", READ_ONLY)
            made.append(group)
        label = f"Layer {k + 1} (z {grid.corner_mm((0, 0, k))[2]:.1f} mm)"
        if group.Label != label:
            group.Label = label
        members = by_layer[k]
        if list(group.Group) != members:
            group.Group = members
        out.append(group)
    for group in groups.values():
        group.Group = []
        fab.Document.removeObject(group.Name)
    return out


def _sync_printed(fab, group, result, made: list) -> list:
    """PrintedPart objects for the result's printed parts (kept by ID); the list, by ID."""
    doc = fab.Document
    existing = {p.PartId: p for p in group.Group if role(p) == "PrintedPart"}
    step_of = {}
    for b in result.fab.layout.bricks:
        if b.printed_part is not None and b.step is not None:
            step_of[b.printed_part] = b.step
    method = ""
    if result.fab.print_parts is not None:
        method = result.fab.print_parts.method
    changes = result.report.get("changes")
    reprint = (set(changes.get("parts_reprinted", [])) if changes
               else {p.id for p in result.fab.printed})
    out = []
    for part in result.fab.printed:
        obj = existing.pop(part.id, None)
        if obj is None:
            obj = doc.addObject("Part::FeaturePython", "PrintedPart")
            PrintedPart(obj)
            made.append(obj)
        obj.Shape = (bridge.occ_to_part(part.solid) if part.solid is not None
                     else bridge.trimesh_to_part(part.mesh))
        obj.PartId = part.id
        obj.Reprint = part.id in reprint
        label = f"{part.id} (reprint)" if changes and obj.Reprint else part.id
        if obj.Label != label:
            obj.Label = label
        obj.BrickIds = [int(b) for b in part.bricks]
        obj.Cells = int(part.cells)
        obj.VolumeMm3 = float(part.volume_mm3)
        obj.CompleteStuds = len(part.complete_studs)
        obj.IncompleteStuds = list(part.incomplete_studs)
        obj.Sockets = len(part.complete_sockets)
        obj.IncompleteSockets = list(part.incomplete_sockets)
        engaged = part.engaged
        obj.Clamping = "yes" if engaged["clamps"] else engaged["why"]
        obj.Engraved = bool(part.engraved)
        obj.PrintTime = float(part.print_s or 0.0)
        obj.PrintTimeMethod = method
        obj.Step = int(step_of.get(part.id, 0))
        out.append(obj)
    for obj in existing.values():
        doc.removeObject(obj.Name)
    return out


class Prototypes:
    """The document's brick prototypes, found or made on demand (one per part and colour)."""

    def __init__(self, doc):
        self.doc = doc
        self.made: list = []
        self.group = next((o for o in doc.Objects if role(o) == PROTOTYPES_ROLE), None)
        self.by_key = {}
        if self.group is not None:
            for p in self.group.Group:
                self.by_key[(p.PartNumber, rgb_key(p.Color))] = p
        self.shapes = {}

    def get(self, part: str, rgb: tuple):
        """The prototype of ``part`` in colour ``rgb`` (made if missing)."""
        key = (part, rgb_key(rgb))
        found = self.by_key.get(key)
        if found is not None:
            return found
        if self.group is None:
            self.group = new_group(self.doc, "BrickPrototypes", PROTOTYPES_ROLE, "Brick prototypes")
            self.made.append(self.group)
        obj = make_prototype(self.doc, part, key[1], self._shape(part))
        self.group.addObject(obj)
        self.by_key[key] = obj
        self.made.append(obj)
        return obj

    def touched(self) -> list:
        """The prototypes group and its prototypes (those this run may have changed)."""
        return [] if self.group is None else [self.group] + list(self.group.Group)

    def _shape(self, part: str):
        """The LEGO solid of ``part`` (shared with other colours of the same part)."""
        if part not in self.shapes:
            same = next((p for (n, _), p in self.by_key.items() if n == part), None)
            if same is not None:
                self.shapes[part] = same.Shape
            else:
                from core.parts.brick_solids import brick_solid

                spec = BY_NUMBER[part]
                solid = brick_solid(spec.footprint[0], spec.footprint[1], spec.layers)
                self.shapes[part] = bridge.occ_to_part(solid.shape.wrapped)
        return self.shapes[part]
