"""Undo and redo of every workbench action, in ``freecadcmd`` (FreeCAD 0.20 and 1.x).

Each action runs in one transaction, as its command does.  After Undo the
document must be exactly as before the action, and after Redo exactly as
after it: the same objects under the same names and types, with the same
links, placements, groups, labels, visibility and Fabrickator properties.
FreeCAD 1.0 crashes when a transaction deletes an ``App::Link`` that still
links (FreeCAD/FreeCAD#18326); :mod:`FabrickatorWorkbench.undo` is what
keeps these tests alive there.
"""

from __future__ import annotations

import unittest

import FreeCAD as App

from TestFabrickatorApp import FabrickatorTestCase, fab, padded_body

#: Properties compared, where an object has them (Fabrickator's and FreeCAD's own).
COMPARED = ("Label", "Visibility", "LayoutJson", "ReportJson", "StepsJson", "Status", "Seed",
            "Scale", "BrickSet", "Boxes", "PartNumber", "Cell", "Size", "Kind", "Step",
            "PrintedPart", "BrickId", "Changed", "PartId", "Reprint", "PartEdits", "StudFit",
            "SocketFit")
LINKS = ("LinkedObject", "Group", "Contents", "Regions", "Source")


def state(doc) -> dict:
    """Everything a user could see change in ``doc``, by object name."""
    out = {}
    for obj in doc.Objects:
        row = {"type": obj.TypeId}
        for name in COMPARED:
            if name in obj.PropertiesList:
                value = getattr(obj, name)
                row[name] = list(value) if isinstance(value, (list, tuple)) else value
        for name in LINKS:
            if name in obj.PropertiesList:
                value = getattr(obj, name)
                if isinstance(value, (list, tuple)):
                    row[name] = [o.Name for o in value if o is not None]
                else:
                    row[name] = value.Name if value is not None else None
        if "Placement" in obj.PropertiesList:
            p = obj.Placement
            row["Placement"] = tuple(round(v, 9) for v in tuple(p.Base) + tuple(p.Rotation.Q))
        if "Shape" in obj.PropertiesList and obj.TypeId != "App::Link":
            row["Volume"] = round(obj.Shape.Volume, 6) if not obj.Shape.isNull() else None
        out[obj.Name] = row
    return out


class TestUndo(FabrickatorTestCase):
    """Every action is one undo step that undoes and redoes exactly."""

    def action(self, name: str, do) -> None:
        """Run ``do()`` as one transaction ``name``; then Undo, Redo and Undo again, and
        check the document after each against the states before and after."""
        doc = self.doc
        before = state(doc)
        doc.openTransaction(name)
        do()
        doc.commitTransaction()
        after = state(doc)
        self.assertNotEqual(after, before, f"{name} changed nothing")
        doc.undo()
        self.assertEqual(state(doc), before, f"undo {name}")
        doc.redo()
        self.assertEqual(state(doc), after, f"redo {name}")
        doc.undo()
        self.assertEqual(state(doc), before, f"second undo {name}")
        doc.redo()
        self.assertEqual(state(doc), after, f"second redo {name}")

    def test_every_action_undoes_and_redoes_exactly(self):
        body, _, pad = padded_body(self.doc)
        made = {}

        def legofy():
            made["fab"] = fab().make_fabrication(body)
            self.doc.recompute()

        self.action("Legofy", legofy)
        f = made["fab"]
        self.assertTrue(f.Status.startswith("ok"), f.Status)
        self.action("High-res brush", lambda: (
            fab().mark_high_res(f, bricks=[fab().bricks(f)[0]]), self.doc.recompute()))
        self.assertEqual(len(fab().printed_parts(f)), 1)
        self.action("Lay out", lambda: (setattr(f, "Seed", 7), self.doc.recompute()))
        lego = [b for b in fab().bricks(f) if b.Kind == "lego"]
        self.action("Merge bricks", lambda: (fab().merge_bricks(f, lego[-2:]),
                                             self.doc.recompute()))
        self.action("Unmark", lambda: (fab().unmark(f, fab().bricks(f)), self.doc.recompute()))
        self.action("Edit model", lambda: (setattr(pad, "Length", pad.Length.Value + 9.6),
                                           self.doc.recompute()))
        self.assertTrue(fab().ghosts(f) or any(b.Changed for b in fab().bricks(f)))
        self.action("Clear changes", lambda: fab().clear_changes(f))

        def delete():
            fab().remove_owned(f)
            self.doc.removeObject(f.Name)

        self.action("Delete", delete)
        self.assertEqual(fab().fabrications(self.doc), [])

    def test_save_after_undo_reopens_whole(self):
        body, _, _ = padded_body(self.doc)
        self.doc.openTransaction("Legofy")
        f = fab().make_fabrication(body)
        self.doc.recompute()
        self.doc.commitTransaction()
        self.doc.openTransaction("Lay out")
        f.Seed = 3
        self.doc.recompute()
        self.doc.commitTransaction()
        self.doc.undo()
        expected = state(self.doc)
        path = self.path("undone.FCStd")
        self.doc.saveAs(path)
        App.closeDocument(self.doc.Name)
        self.doc = App.openDocument(path)
        self.assertEqual(state(self.doc), expected)


if __name__ == "__main__":
    unittest.main()
