"""The Stress display mode of a Fabrication: bricks coloured by how hard their joints work.

The core's force check (:mod:`core.forces`, report.json ``stability.force``)
gives every brick a *utilisation*: the pull on its studs against the clutch
they hold, or its bending against what it takes; up to 1 the brick holds.
In the Stress mode every LEGO brick and printed part is drawn dark at 0,
red at 1 and white above 1 (the scale of ``stress.png``,
:func:`core.colours.stress_rgb`) or when it is unsupported:
the white bricks are the failing ones, the reddest the closest to failing.
A brick the check did not cover keeps its LEGO colour.  The Normal mode
gives every brick its LEGO colour back.

The objects and their utilisations come from the Fabrication's proxy
(``utilisations``); the colours are link material overrides on the bricks
(as the ghosts of removed bricks have) and the shape colour of the printed
parts.
"""

from __future__ import annotations


from core.colours import stress_rgb
from FabrickatorWorkbench.viewproviders.printed_part import PRINTED_COLOUR

#: The display modes of a Fabrication.
NORMAL, STRESS = "Normal", "Stress"
MODES = [NORMAL, STRESS]


def colour(utilisation: float) -> tuple[float, float, float]:
    """The stress colour of ``utilisation``: the scale of :func:`core.colours.stress_rgb`
    (dark at 0, red at 1, white above 1 and for inf), the same as ``stress.png``'s."""
    return tuple(float(v) for v in stress_rgb([float(utilisation)])[0])


def apply(fab, stress: bool) -> int:
    """Draw the bricks and printed parts of Fabrication ``fab`` in stress colours
    (``stress``) or in their own (not); returns how many were coloured by stress.
    No-op without the GUI (no view objects) or without a force check."""
    ask = getattr(getattr(fab, "Proxy", None), "utilisations", None)
    found = ask(fab) if ask is not None else None
    if not found:
        return 0
    coloured = 0
    for obj, utilisation in found:
        view = getattr(obj, "ViewObject", None)
        if view is None:
            continue
        rgb = colour(utilisation) if stress and utilisation is not None else None
        if hasattr(view, "OverrideMaterial"):
            _link_colour(view, rgb)
        elif hasattr(view, "ShapeColor"):
            wanted = rgb or PRINTED_COLOUR
            if tuple(view.ShapeColor[:3]) != tuple(wanted):
                view.ShapeColor = wanted
        coloured += rgb is not None
    return coloured


def _link_colour(view, rgb) -> None:
    """Override the material of a brick's link with ``rgb``, or take the override off."""
    if rgb is None:
        if view.OverrideMaterial:
            view.OverrideMaterial = False
        return
    material = view.ShapeMaterial
    if tuple(material.DiffuseColor[:3]) != tuple(rgb) or material.Transparency:
        material.DiffuseColor = rgb
        material.Transparency = 0.0
        view.ShapeMaterial = material
    if not view.OverrideMaterial:
        view.OverrideMaterial = True
