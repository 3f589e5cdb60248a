"""The layout shown in the 3D view while a recompute goes on.

A recompute tells the layout as soon as its bricks are decided (:class:`core.pipeline.LayoutReady`),
seconds before the printed parts are cut and the forces and the build order checked.
:class:`LayoutPreview` draws those bricks over the 3D view at once: on a first layout all of
them, later the bricks that are new or moved against the Fabrication's stored layout, LEGO in
the highlight colour and the bricks to print in the printed colour, each a box with its edges.
It is a node of the view's scene graph, not a document object, so it changes nothing that
undo or a failed recompute would have to put back; it goes when the recompute ends.
"""

from __future__ import annotations

import json
import time

import FreeCAD as App

from core.model import Layout
from FabrickatorWorkbench.objects.prototype import HIGHLIGHT_COLOUR
from FabrickatorWorkbench.viewproviders.printed_part import PRINTED_COLOUR

#: Name of the preview's node in the scene graph.
NODE_NAME = "FabrickatorLayoutPreview"

#: The LEGO bricks of a first layout, which has no highlighted bricks to show.
FIRST_COLOUR = (0.75, 0.75, 0.78)

#: Transparency of the preview's faces: the old layout shows through a little.
TRANSPARENCY = 0.1

#: The 12 edges of a box by the corner numbers of :func:`_corners`.
_EDGES = ((0, 1), (1, 3), (3, 2), (2, 0), (4, 5), (5, 7), (7, 6), (6, 4),
          (0, 4), (1, 5), (2, 6), (3, 7))
#: The 6 faces of a box, counter-clockwise seen from outside.
_FACES = ((1, 3, 2, 0), (6, 7, 5, 4), (4, 5, 1, 0), (3, 7, 6, 2), (2, 6, 4, 0), (5, 7, 3, 1))


class LayoutPreview:
    """The preview of Fabrication ``fab``'s next layout in the active 3D view (none without
    the GUI): :meth:`show` is :func:`core.pipeline.run`'s ``on_layout``, :meth:`close`
    removes what it drew.  ``shown_after`` is the seconds from the preview's start to the
    moment the layout was drawn (None until then)."""

    def __init__(self, fab, title: str):
        self.title = title
        self.node = None
        self.graph = None
        self.started = time.perf_counter()
        self.shown_after: float | None = None
        self.drawn = 0
        self.before = _stored_keys(fab)

    def show(self, ready) -> None:
        """Draw ``ready``'s new and to-print bricks and repaint the view now."""
        if not App.GuiUp:
            return
        import FreeCADGui as Gui

        view = getattr(Gui.ActiveDocument, "ActiveView", None) if Gui.ActiveDocument else None
        if view is None or not hasattr(view, "getSceneGraph"):
            return
        first = self.before is None
        printed = [b for b in ready.layout.bricks if b.id in ready.printed]
        lego = [b for b in ready.layout.bricks if b.id not in ready.printed
                and (first or (b.cell, b.size, b.kind) not in self.before)]
        self.close()
        self.graph = view.getSceneGraph()
        self.node = _node(ready.layout, ((lego, FIRST_COLOUR if first else HIGHLIGHT_COLOUR),
                                         (printed, PRINTED_COLOUR)))
        self.graph.addChild(self.node)
        self.drawn = len(lego) + len(printed)
        status = Gui.getMainWindow().statusBar()
        status.showMessage(f"{self.title}: layout ready, {len(ready.layout.bricks)} bricks "
                           f"({len(printed)} to print); cutting the printed parts and checking "
                           f"the forces")
        _repaint(view)
        self.shown_after = time.perf_counter() - self.started

    def close(self) -> None:
        """Remove the preview from the scene graph (nothing when none is shown)."""
        if self.node is not None and self.graph is not None:
            self.graph.removeChild(self.node)
        self.node = self.graph = None


def _stored_keys(fab) -> set | None:
    """(cell, size, kind) of every brick of ``fab``'s stored layout; None when it has none."""
    try:
        layout = Layout.from_json(json.loads(fab.LayoutJson)) if fab.LayoutJson else None
    except (ValueError, KeyError, TypeError):
        layout = None
    return None if layout is None else {(b.cell, b.size, b.kind) for b in layout.bricks}


def _corners(lo, hi) -> list[tuple[float, float, float]]:
    """The 8 corners of box ``lo``..``hi``: corner n has x from bit 2, y from bit 1, z from bit 0."""
    return [(hi[0] if n & 4 else lo[0], hi[1] if n & 2 else lo[1], hi[2] if n & 1 else lo[2])
            for n in range(8)]


def _node(layout: Layout, sets):
    """A separator with each (bricks, colour) of ``sets`` as boxes with dark edges."""
    from pivy import coin

    root = coin.SoSeparator()
    root.setName(NODE_NAME)
    style = coin.SoPickStyle()
    style.style = coin.SoPickStyle.UNPICKABLE
    root.addChild(style)
    hints = coin.SoShapeHints()
    hints.vertexOrdering = coin.SoShapeHints.COUNTERCLOCKWISE
    hints.shapeType = coin.SoShapeHints.SOLID
    root.addChild(hints)
    for bricks, colour in sets:
        if not bricks:
            continue
        points, faces, edges = [], [], []
        for brick in bricks:
            lo, hi = layout.grid.box_mm(brick.cell, brick.size)
            base = len(points)
            points += _corners(lo, hi)
            for face in _FACES:
                faces += [base + i for i in face] + [-1]
            for a, b in _EDGES:
                edges += [base + a, base + b, -1]
        group = coin.SoSeparator()
        coords = coin.SoCoordinate3()
        coords.point.setValues(0, len(points), points)
        group.addChild(coords)
        material = coin.SoMaterial()
        material.diffuseColor = colour
        material.transparency = TRANSPARENCY
        group.addChild(material)
        shape = coin.SoIndexedFaceSet()
        shape.coordIndex.setValues(0, len(faces), faces)
        group.addChild(shape)
        lines = coin.SoSeparator()
        line_colour = coin.SoBaseColor()
        line_colour.rgb = tuple(0.4 * c for c in colour)
        lines.addChild(line_colour)
        edge_set = coin.SoIndexedLineSet()
        edge_set.coordIndex.setValues(0, len(edges), edges)
        lines.addChild(edge_set)
        group.addChild(lines)
        root.addChild(group)
    return root


def _repaint(view) -> None:
    """Paint ``view`` and the status bar now, inside a recompute, without handling the user's
    input (the recompute still runs)."""
    from PySide import QtCore, QtGui

    view.redraw()
    QtGui.QApplication.processEvents(QtCore.QEventLoop.ExcludeUserInputEvents)
