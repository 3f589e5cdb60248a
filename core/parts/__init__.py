"""The printed parts: what of the model is kept exact, and how it joins the LEGO around it.

:mod:`~core.parts.printed` cuts the model inside the marked bricks into solids, each
kept whole, with the Booleans of :mod:`~core.parts.booleans` (manifold3d for meshes,
OpenCascade for B-rep) and its id engraved by :mod:`~core.parts.engraving`; a part is a
:class:`~core.parts.printed_part.PrintedPart` (:mod:`~core.parts.printed_part`).
:mod:`~core.parts.interfaces` and :mod:`~core.parts.connectors` give a part the studs and
sockets where it meets bricks, with the fit of :class:`~core.parts.interfaces.Fit`;
:mod:`~core.parts.brick_solids` builds exact LEGO geometry (studs, tubes, walls) with
tagged faces; :mod:`~core.parts.thickness` finds walls too thin to print;
:mod:`~core.parts.calibration` prints the strip that finds a printer's fit.  A part's
solid contains the model inside its bricks, and its studs fit real LEGO.
"""
