"""Undo and redo of the brick links, made safe on FreeCAD 1.0.

Every brick (and every ghost of a removed brick) is an ``App::Link``.  FreeCAD
1.0 cannot delete, inside an undo or a redo, an ``App::Link`` whose
``LinkedObject`` is set: the transaction stops with "Exception on undo:
invalid container", leaves the document half undone, and FreeCAD crashes
soon after (FreeCAD/FreeCAD#18326, #17900, #18225; a plain "Make Link" then
Ctrl+Z does it).  Undoing a Legofy, a brush or a re-layout deletes the links
it made; redoing a re-layout deletes the links it took off.

A bare link (no ``LinkedObject``) is deleted cleanly, and FreeCAD announces
every deletion, the transactions' own included, before it happens.  So
:class:`LinkGuard`, a document observer, unlinks a Fabrickator link just
before it is deleted.  The transaction being applied records that change
too, so the redo (or undo) that brings the link back links it again.  Undo
stays on and every action stays one undo step.
"""

from __future__ import annotations

import FreeCAD as App

#: Roles (``FabrickatorRole``) of the ``App::Link`` objects Fabrickator makes.
LINK_ROLES = ("Brick", "RemovedBrick")


class LinkGuard:
    """Document observer: a Fabrickator ``App::Link`` loses its link just before deletion."""

    def slotDeletedObject(self, obj):
        if (obj.TypeId == "App::Link" and getattr(obj, "FabrickatorRole", None) in LINK_ROLES
                and obj.LinkedObject is not None):
            obj.LinkedObject = None


def install() -> LinkGuard:
    """Register the one :class:`LinkGuard` with FreeCAD (idempotent); returns it.

    The observer is kept by FreeCAD's application object, which owns the
    observers of every add-on; registering twice returns the first one.
    """
    guard = getattr(App, "_fabrickator_link_guard", None)
    if guard is None:
        guard = LinkGuard()
        App.addDocumentObserver(guard)
        App._fabrickator_link_guard = guard
    return guard
