"""Fabrickator's FreeCAD layer: translation between a FreeCAD document and
:mod:`core`.  It holds no algorithm; everything here calls into ``core``."""
