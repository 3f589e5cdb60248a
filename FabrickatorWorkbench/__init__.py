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
"""

_API = ("make_fabrication", "fabrications", "fabrication_of", "mark_high_res", "unmark",
        "merge_bricks", "split_bricks", "brick_boxes", "bricks", "printed_parts", "regions",
        "report", "steps", "layout", "core_printed_parts", "export", "remove_owned",
        "import_model", "reload_model", "legofy_file", "recompute", "clear_changes", "ghosts",
        "feed_file", "model_name", "make_calibration_strip")


def __getattr__(name):
    if name in _API:
        from FabrickatorWorkbench import make
        return getattr(make, name)
    raise AttributeError(f"module 'FabrickatorWorkbench' has no attribute {name!r}")


def __dir__():
    return sorted(list(globals()) + list(_API))
