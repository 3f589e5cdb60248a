"""The Fabrication object: one fabricated part, parametric in its Source.

An ``App::FeaturePython`` whose proxy is :class:`Fabrication`.
Its inputs are the Source (any solid or a mesh feature), the brick set,
stud and socket fit, seed, scale, the high-res regions, the merge/split edits and,
for the force check, the Ground, the Clutch and the Loads (:mod:`.load`);
its recompute runs the core pipeline (:mod:`.fabricate`) and keeps the
result in the document: the layout, report and steps as JSON properties,
one tree object per brick grouped by layer, and PrintedPart objects.  So a
saved document reopens with everything in place and no recompute.

It is not a group itself: FreeCAD 0.20 takes any group that links an
object as that object's group, which would clash with the user's groups
holding the Source.  Its ``Contents`` (the layer, printed-part and region
groups) show under it in the tree through its view provider.
"""

from __future__ import annotations

from functools import partial

import FreeCAD as App

from FabrickatorWorkbench import log
from FabrickatorWorkbench.objects import fabricate, prototype, tree
from FabrickatorWorkbench.objects.properties import HIDDEN, READ_ONLY, Prop, FeatureProxy
from FabrickatorWorkbench.preferences import setting_default
from FabrickatorWorkbench.viewproviders.brick import apply_ghost_look
from core.request import EFFORTS

QT = App.Qt.QT_TRANSLATE_NOOP

def effort_choices() -> list[str]:
    """The efforts of the core (:data:`core.request.EFFORTS`), its default first (an
    enumeration property takes its first choice as its value)."""
    default = setting_default("effort")
    return [default] + [e for e in EFFORTS if e != default]


#: Value of the hidden ``FabrickatorRole`` property that marks a Fabrication.
ROLE = "Fabrication"


def grounds() -> list[str]:
    """The grounds of the force check (:data:`core.forces.GROUNDS`), the default of the
    one table of defaults first (an enumeration takes its first item)."""
    from core.forces import GROUNDS

    first = setting_default("ground")
    return [first] + [g for g in GROUNDS if g != first]


def clutch():
    """The default clutch of the one table of defaults (``clutch_n``, N) as a force."""
    return App.Units.Quantity(f"{float(setting_default('clutch_n'))} N")

PROPERTIES = (
    Prop("App::PropertyString", "FabrickatorRole", "Base",
         QT("App::Property", "Fabrickator object role"), ROLE, HIDDEN),
    Prop("App::PropertyLink", "Source", "Fabrication",
         QT("App::Property", "The part to build: a solid (Body, Part feature, STEP) or a mesh")),
    Prop("App::PropertyString", "BrickSet", "Fabrication",
         QT("App::Property", "Bricks to use: all, plates, bricks, design numbers (3001,3024) "
                             "or names like plate2x4; must contain the 1x1 plate 3024"), "all"),
    Prop("App::PropertyStringList", "Inventory", "Fabrication",
         QT("App::Property", "Files of the LEGO parts you own (Rebrickable CSV, BrickLink XML or "
                             "LDraw .ldr/.mpd), used first and in their colours; empty: every "
                             "brick is bought")),
    Prop("App::PropertyBool", "InventoryOnly", "Fabrication",
         QT("App::Property", "Build only from the Inventory's parts, or fail naming the cells "
                             "they cannot cover"), partial(setting_default, "inventory_only")),
    Prop("App::PropertyString", "BuyColour", "Fabrication",
         QT("App::Property", "Colour of the bricks to buy (an LDraw or BrickLink name)"),
         partial(setting_default, "colour")),
    Prop("App::PropertyDistance", "StudFit", "Fabrication",
         QT("App::Property", "Printed studs are 4.8 mm + this across (signed; larger clamps "
                             "tighter); find your printer's value with the Calibration strip"),
         partial(setting_default, "stud_fit")),
    Prop("App::PropertyDistance", "SocketFit", "Fabrication",
         QT("App::Property", "Printed sockets are 4.8 mm + this between the walls a real stud "
                             "touches (signed; smaller clamps tighter); see the Calibration strip"),
         partial(setting_default, "socket_fit")),
    Prop("App::PropertyString", "Printer", "Fabrication",
         QT("App::Property", "PrusaSlicer printer preset the parts are timed and packed for "
                             "(python -m core printers lists them); empty: the preference's "
                             "printer, or the MK3S"), ""),
    Prop("App::PropertyInteger", "Seed", "Fabrication",
         QT("App::Property", "Seed of the layout: the same seed gives the same layout"),
         partial(setting_default, "seed")),
    Prop("App::PropertyFloat", "Scale", "Fabrication",
         QT("App::Property", "Scale applied to the Source before it is built from LEGO"),
         partial(setting_default, "scale")),
    Prop("App::PropertyVector", "CellSize", "Fabrication",
         QT("App::Property", "Size of one 1x1 plate cell (stud pitch, pitch, plate height), mm"),
         None, READ_ONLY),
    Prop("App::PropertyEnumeration", "Effort", "Fabrication",
         QT("App::Property", "How hard the layout is optimised after the greedy pass: fast (the "
                             "greedy layout only), normal (a few seconds for 2,000 cells) or best "
                             "(up to a minute): fewer separate pieces, weak points and bricks"),
         effort_choices),
    Prop("App::PropertyBool", "LowerBound", "Fabrication",
         QT("App::Property", "Also solve the exact lower bound on the brick count and the fewest "
                             "bricks of a layout in one piece like this one (up to 20 s each), "
                             "shown by the Report command; off: the first bound only when it "
                             "costs no more than the layout"),
         partial(setting_default, "lower_bound")),
    Prop("App::PropertyFloat", "SecondsPerBrick", "Fabrication",
         QT("App::Property", "Assembly estimate: seconds to place one LEGO brick"),
         partial(setting_default, "seconds_per_brick")),
    Prop("App::PropertyFloat", "SecondsPerPart", "Fabrication",
         QT("App::Property", "Assembly estimate: seconds to insert one printed part"),
         partial(setting_default, "seconds_per_part")),
    Prop("App::PropertyBool", "SlicePrintTimes", "Fabrication",
         QT("App::Property", "Slice the whole part and the printed parts with PrusaSlicer on "
                             "recompute (slower); otherwise print times are estimated"), False),
    Prop("App::PropertyBool", "FitGrid", "Fabrication",
         QT("App::Property", "Shift the grid (up to one stud in x and y) so that the high-res "
                             "regions print the least; off: the grid is centred on the part"),
         partial(setting_default, "fit_grid")),
    Prop("App::PropertyInteger", "Hollow", "Fabrication",
         QT("App::Property", "Shell thickness in studs of a hollowed part, with pillars under "
                             "its roof; 0: solid; -1: automatic (hollow with 2 studs when the "
                             "part has 50,000 cells or more, keeps at most two thirds of them and "
                             "saves more than a third of the bricks)"),
         partial(setting_default, "hollow")),
    Prop("App::PropertyBool", "KeepLayout", "Fabrication",
         QT("App::Property", "Iterate on the previous result: keep its layout wherever the part "
                             "and the regions did not change and reprint only changed printed "
                             "parts (not when the seed or scale changed or the Source moved)"),
         True),
    Prop("App::PropertyEnumeration", "Ground", "Forces",
         QT("App::Property", "What the build stands on for the force check: table (its bottom "
                             "layer only presses down) or baseplate (clamped to a LEGO "
                             "baseplate)"), grounds),
    Prop("App::PropertyForce", "Clutch", "Forces",
         QT("App::Property", "Tension one stud contact point holds (a LEGO stud is gripped at 3 "
                             "points under 2-wide bricks, 4 under 1-wide)"), clutch),
    Prop("App::PropertyLinkList", "Loads", "Forces",
         QT("App::Property", "Loads: masses resting on the bricks (a phone, a lens, a battery)"),
         None, READ_ONLY),
    Prop("App::PropertyLinkList", "Regions", "Fabrication",
         QT("App::Property", "High-res regions: what must be printed exactly"), None, READ_ONLY),
    Prop("App::PropertyLinkList", "Contents", "Fabrication",
         QT("App::Property", "Groups the Fabrication made: regions, printed parts, layers"),
         None, HIDDEN),
    Prop("App::PropertyInteger", "NameSerial", "Fabrication",
         QT("App::Property", "Counter of the object names given to new bricks"), 0, HIDDEN),
    Prop("App::PropertyString", "PartEdits", "Fabrication",
         QT("App::Property", "Merge and split brush edits (JSON)"), "[]", HIDDEN),
    Prop("App::PropertyString", "Status", "Result",
         QT("App::Property", "Outcome of the last recompute"), "not computed", READ_ONLY),
    Prop("App::PropertyInteger", "Plates", "Result",
         QT("App::Property", "Filled 1x1 plate cells"), 0, READ_ONLY),
    Prop("App::PropertyInteger", "Bricks", "Result",
         QT("App::Property", "Bricks in the layout (LEGO and printed)"), 0, READ_ONLY),
    Prop("App::PropertyInteger", "LegoBricks", "Result",
         QT("App::Property", "LEGO bricks in the layout"), 0, READ_ONLY),
    Prop("App::PropertyInteger", "PrintedParts", "Result",
         QT("App::Property", "Printed parts"), 0, READ_ONLY),
    Prop("App::PropertyInteger", "Steps", "Result",
         QT("App::Property", "Assembly steps"), 0, READ_ONLY),
    Prop("App::PropertyInteger", "Components", "Result",
         QT("App::Property", "Separate pieces the bricks form"), 0, READ_ONLY),
    Prop("App::PropertyInteger", "WeakPoints", "Result",
         QT("App::Property", "Bricks whose removal splits the structure"), 0, READ_ONLY),
    Prop("App::PropertyBool", "Stands", "Result",
         QT("App::Property", "The force check: every brick is held with its loads (no joint "
                             "works above what it holds)"), False, READ_ONLY),
    Prop("App::PropertyInteger", "FailingBricks", "Result",
         QT("App::Property", "Bricks whose joints cannot carry them (utilisation above 1, or "
                             "unsupported); the Stress display mode shows them white"), 0, READ_ONLY),
    Prop("App::PropertyString", "Forces", "Result",
         QT("App::Property", "The force check in words: worst joint utilisation, mass carried"),
         "", READ_ONLY),
    Prop("App::PropertyFloat", "SpeedUp", "Result",
         QT("App::Property", "Full print time / the fabrication's time (the LEGO built while "
                             "the printer prints, then the printed parts pressed on); 0 when "
                             "not sliced"), 0.0, READ_ONLY),
    Prop("App::PropertyInteger", "BricksKept", "Result",
         QT("App::Property", "Bricks kept from the previous recompute"), 0, READ_ONLY),
    Prop("App::PropertyInteger", "BricksChanged", "Result",
         QT("App::Property", "Bricks new or changed in the last recompute"), 0, READ_ONLY),
    Prop("App::PropertyStringList", "Changes", "Result",
         QT("App::Property", "What the last recompute changed: bricks to take off (shown as "
                             "ghosts), bricks to add (highlighted), printed parts to reprint"),
         None, READ_ONLY),
    Prop("App::PropertyVector", "GridOrigin", "Result",
         QT("App::Property", "Min corner of cell (0, 0, 0), mm"), None, READ_ONLY),
    Prop("App::PropertyString", "LayoutJson", "Result",
         QT("App::Property", "The layout (layout.json of the core)"), "", HIDDEN),
    Prop("App::PropertyString", "ReportJson", "Result",
         QT("App::Property", "The report (report.json of the core)"), "", HIDDEN),
    Prop("App::PropertyString", "StepsJson", "Result",
         QT("App::Property", "The assembly steps"), "", HIDDEN),
    Prop("App::PropertyFileIncluded", "IterationState", "Result",
         QT("App::Property", "What the next iteration needs of this result (core snapshot, zip)"),
         None, HIDDEN),
    Prop("App::PropertyString", "LastGood", "Result",
         QT("App::Property", "Parameters of the last successful recompute"), "", HIDDEN),
)


class Fabrication(FeatureProxy):
    """Proxy of a Fabrication object; its recompute runs the core pipeline."""

    PROPERTIES = PROPERTIES

    def ensure_properties(self, obj) -> None:
        """Add what is missing (idempotent), with the preferred cell size."""
        super().ensure_properties(obj)
        if obj.CellSize.Length == 0:
            obj.CellSize = fabricate.cell_size()

    def onDocumentRestored(self, obj):
        super().onDocumentRestored(obj)
        retire_clearance(obj)
        tree.restore_bricks(obj)
        if App.GuiUp:
            for proto in tree.prototypes(obj.Document):
                prototype.apply_colour(proto)
            for ghost in tree.ghosts(obj):
                apply_ghost_look(ghost)

    def execute(self, obj):
        fabricate.recompute(obj)

    def utilisations(self, obj) -> list[tuple] | None:
        """What the Stress display mode colours: (object, utilisation) for every LEGO brick
        and printed part of ``obj``, from its report's force check (``stability.force``).
        A printed part has the largest of its bricks'; an unsupported brick has ``inf``, a
        brick the check did not cover None.  None when the report has no force check (a
        result made before it)."""
        return tree.utilisations(obj)

    def remove_owned(self, obj) -> None:
        """Delete everything Fabrication ``obj`` made (:func:`.tree.remove_owned`) and show
        its Source again unless another Fabrication builds it: what its view provider
        does when the user deletes it."""
        tree.remove_owned(obj)
        source = obj.Source
        others = [o for o in obj.Document.Objects
                  if o.Name != obj.Name and is_fabrication(o) and o.Source == source]
        if source is not None and not others:
            source.Visibility = True


#: The property older versions had instead of StudFit and SocketFit: one FDM clearance,
#: a diameter taken off studs and added to holes.
OLD_CLEARANCE = "Clearance"


def retire_clearance(obj) -> bool:
    """Remove an older document's ``Clearance`` property from Fabrication ``obj`` (its
    StudFit and SocketFit, added on restore, take over with their defaults) and say so
    in the Report view; True when there was one.  Idempotent."""
    if OLD_CLEARANCE not in obj.PropertiesList:
        return False
    old = getattr(obj, OLD_CLEARANCE)
    old = float(getattr(old, "Value", old))
    obj.removeProperty(OLD_CLEARANCE)
    log.message(f"{obj.Label}: the old Clearance ({old:g} mm) is replaced by StudFit "
                f"({float(obj.StudFit.Value):+.2f} mm) and SocketFit "
                f"({float(obj.SocketFit.Value):+.2f} mm); the next recompute uses them (the "
                f"Calibration strip finds your printer's)")
    return True


def is_fabrication(obj) -> bool:
    """True for a Fabrication object."""
    return obj is not None and getattr(obj, "FabrickatorRole", None) == ROLE
