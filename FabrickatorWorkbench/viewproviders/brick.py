"""How bricks' links look in the 3D view beyond their prototype's colour.  GUI only.

Ghosts (bricks the last recompute took off, :mod:`FabrickatorWorkbench.objects.tree`)
link to the prototype their brick had, so they keep its shape; their link's
material is overridden to a transparent grey so that they read as "was here",
and they cannot be picked (a click goes through them to the bricks).
"""

from __future__ import annotations

#: Colour and transparency (0..1) of ghosts.
GHOST_COLOUR = (0.55, 0.55, 0.58)
GHOST_TRANSPARENCY = 0.7


def apply_ghost_look(obj) -> None:
    """Draw the ghost ``obj`` grey and transparent (no-op without a view object)."""
    view = getattr(obj, "ViewObject", None)
    if view is None or not hasattr(view, "ShapeMaterial"):
        return
    material = view.ShapeMaterial
    if (tuple(material.DiffuseColor[:3]) != GHOST_COLOUR
            or abs(material.Transparency - GHOST_TRANSPARENCY) > 1e-6):
        material.DiffuseColor = GHOST_COLOUR
        material.Transparency = GHOST_TRANSPARENCY
        view.ShapeMaterial = material
    if not view.OverrideMaterial:
        view.OverrideMaterial = True
    if getattr(view, "Selectable", False):
        view.Selectable = False
