"""Suggest high-res regions: the core's suggestions (core/suggest.py) as region objects.

Each suggestion becomes one HighResRegion of the Fabrication (Bricks mode, its box in
the Source's mm), labelled with its reason and carrying it in ``Reason``, for the user
to keep, delete or grow in the brush panel; all of them in one undo transaction.  The
core finds them in the Source as the Fabrication hands it over (its scale), so the
command line's ``python -m core suggest`` on the same file gives the same boxes.
"""

from __future__ import annotations

import tempfile

from core.request import DEFAULTS
from FabrickatorWorkbench import bridge, log, make
from FabrickatorWorkbench.commands.base import (Command, no_task_dialog, recompute_or_fail,
                                                selected_fabrication, transaction)

#: The property of a suggested region that holds its reason.
REASON = "Reason"


class SuggestRegions(Command):
    NAME = "Fabrickator_SuggestRegions"
    ICON = "HighResBrush"
    MENU = "S&uggest high-res regions"
    TIP = ("Find the holes, pins and thin walls that LEGO cannot hold and mark each as a "
           "high-res region with its reason (keep, delete or grow them in the brush panel)")

    def IsActive(self):
        return selected_fabrication(computed=False) is not None and no_task_dialog()

    def run(self):
        suggest_regions(selected_fabrication(computed=False))


def suggestions(fab):
    """The core's suggestions for ``fab``'s Source and the Source-mm boxes of their regions:
    ``(Suggestions, [(x0, y0, z0, x1, y1, z1), ...])``."""
    from core import suggest
    from core.io import meshes as mesh_io

    scale = float(fab.Scale)
    with tempfile.TemporaryDirectory(prefix="fabrickator-suggest-") as work:
        model = mesh_io.load_model(bridge.write_source(fab.Source, work), scale=scale)
        found = suggest.suggest(model, DEFAULTS["suggest_tolerance"], min_speedup=DEFAULTS["suggest_speedup"])
    boxes = [tuple(float(v) / scale for v in (r.box - model.offset_mm).ravel()) for r in found.regions]
    return found, boxes


def suggest_regions(fab, recompute: bool = True) -> list:
    """Add one region per suggestion to ``fab`` in one undo transaction and recompute
    (with ``recompute``); the regions made (none when it failed: the document is then as
    it was and the Report view says why)."""
    made: list = []
    done = False
    with transaction(fab.Document, "Suggest high-res regions"):
        found, boxes = suggestions(fab)
        for n, (region, box) in enumerate(zip(found.regions, boxes), 1):
            obj = make.mark_high_res(fab, box=box, label=f"Suggested {n}: {region.reason}")
            obj.addProperty("App::PropertyString", REASON, "Region",
                            "Why Fabrickator suggests printing this region, and where")
            setattr(obj, REASON, f"{region.reason} at {region.where}")
            made.append(obj)
        for warning in found.warnings:
            log.warning(warning)
        log.message(f"{len(made)} high-res region(s) suggested, marking cells that hold "
                    f"{found.share:.0%} of the part ({found.cells_share:.0%} of its cells)")
        if made and recompute:
            recompute_or_fail(fab)
        done = True
    return made if done else []
