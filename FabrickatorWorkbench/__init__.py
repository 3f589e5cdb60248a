"""Fabrickator's FreeCAD layer: translation between a FreeCAD document and :mod:`core`.

It holds no algorithm; everything here calls into ``core``.  The scripting
API (:mod:`FabrickatorWorkbench.make`) is available from the package itself,
loaded on first use so that importing the package at FreeCAD start-up costs
nothing::

    import FabrickatorWorkbench as fab
    f = fab.make_fabrication(obj)
    fab.mark_high_res(f, box=(0, 0, 0, 20, 20, 10))
    obj.Document.recompute()
    fab.export(f, "/tmp/out")

Importing the package loads this repository's ``core`` (:func:`.deps.load_core`), so
that the modules below, which import ``core`` at their top, get it and not another
add-on's; a clash is one line in the Report view.  It imports nothing else: FreeCAD
runs ``Init.py``, which imports :mod:`.deps` from here, before the venv's numpy is
first on ``sys.path``.

The layers, top to bottom, each importing only those below it:

* :mod:`.commands` and :mod:`.taskpanels` (GUI only);
* :mod:`.make`, the scripting API the commands and panels use too;
* :mod:`.objects` (document objects and their recompute), then
  :mod:`.viewproviders` (attached by the layers above when the GUI is up);
* :mod:`.bridge`, :mod:`.preferences`, :mod:`.log`, :mod:`.deps` and :mod:`core`.

Imports sit at module top, except FreeCAD's GUI modules in code ``freecadcmd`` loads
and the heavy packages (cadquery, OCP, trimesh, scipy, ...; the ``core`` modules that
load them): those are imported where they are used (``tests/core/test_imports.py``).
"""

from FabrickatorWorkbench import deps

_API = ("make_fabrication", "fabrications", "fabrication_of", "mark_high_res", "unmark",
        "merge_bricks", "split_bricks", "brick_boxes", "bricks", "printed_parts", "regions",
        "make_load", "loads",
        "report", "bom", "steps", "step_notes", "layout", "export", "remove_owned",
        "import_model", "reload_model", "legofy_file", "recompute", "clear_changes", "ghosts",
        "feed_file", "model_name", "make_calibration_strip")


try:
    deps.load_core()
except ImportError as _clash:
    deps.report(str(_clash))


def __getattr__(name):
    if name in _API:
        from FabrickatorWorkbench import make
        return getattr(make, name)
    raise AttributeError(f"module 'FabrickatorWorkbench' has no attribute {name!r}")


def __dir__():
    return sorted(list(globals()) + list(_API))
