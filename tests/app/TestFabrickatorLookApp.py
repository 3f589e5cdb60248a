"""App tests (freecadcmd) of how a Fabrication's bricks look, without the GUI (issue 13):
the colour a document stores for its bricks is the one the BOM orders, the palette
preference changes it on recompute, and the brick's own properties lead the property view.
"""

from __future__ import annotations

import FreeCAD as App

import FabrickatorWorkbench as fab
from TestFabrickatorApp import FabrickatorTestCase, padded_body


class TestLookApp(FabrickatorTestCase):
    def fabrication(self):
        body, _, _ = padded_body(self.doc)
        f = fab.make_fabrication(body)
        self.doc.recompute()
        self.assertTrue(f.Status.startswith("ok"), f.Status)
        return f

    def test_stored_brick_colour_is_the_bom_colour_and_follows_the_palette(self):
        from core import colours
        from core.instructions import bom
        from FabrickatorWorkbench import preferences
        from FabrickatorWorkbench.objects import tree
        from FabrickatorWorkbench.objects.prototype import rgb_key

        f = self.fabrication()
        grey = rgb_key(colours.rgb(colours.BOM_COLOR))
        self.assertEqual({rgb_key(b.LinkedObject.Color) for b in fab.bricks(f)}, {grey})
        ordered = {r.ldraw_color for r in bom.lines(tree.stored_layout(f)) if r.kind == "lego"}
        self.assertEqual({rgb_key(colours.rgb(c)) for c in ordered}, {grey})
        preferences.set("Palette", "random")
        try:
            f.touch()
            self.doc.recompute()
            shown = {rgb_key(b.LinkedObject.Color) for b in fab.bricks(f)}
            self.assertLessEqual(shown, {rgb_key(colours.rgb(c)) for c in colours.RANDOM_CODES})
            self.assertGreater(len(shown), 1)
        finally:
            preferences.reset("Palette")

    def test_brick_properties_sort_before_the_link_properties(self):
        from FabrickatorWorkbench.objects.prototype import LINK_PROPERTIES_HIDDEN

        f = self.fabrication()
        brick = fab.bricks(f)[0]
        groups = {brick.getGroupOfProperty(p) for p in ("PartNumber", "Cell", "Step", "Changed")}
        link = brick.getGroupOfProperty("LinkedObject")
        self.assertEqual(len(groups), 1)
        # FreeCAD's property view shows groups in the order of their names
        self.assertLess(groups.pop(), link)
        for name in LINK_PROPERTIES_HIDDEN:
            self.assertIn("Hidden", brick.getEditorMode(name), name)
        self.assertNotIn("Hidden", brick.getEditorMode("LinkedObject"))

    def test_saved_document_keeps_the_prototypes_group_and_colours(self):
        f = self.fabrication()
        colours_before = {b.Name: tuple(b.LinkedObject.Color) for b in fab.bricks(f)}
        path = self.path("look.FCStd")
        self.doc.saveAs(path)
        App.closeDocument(self.doc.Name)
        self.doc = App.openDocument(path)
        f = fab.fabrications(self.doc)[0]
        self.assertEqual({b.Name: tuple(b.LinkedObject.Color) for b in fab.bricks(f)},
                         colours_before)
        from FabrickatorWorkbench.objects import tree

        self.assertEqual(len([o for o in self.doc.Objects
                              if tree.role(o) == tree.PROTOTYPES_ROLE]), 1)
        self.assertTrue(tree.prototypes(self.doc))

    def test_document_from_an_older_version_gets_todays_property_view(self):
        from FabrickatorWorkbench.objects.prototype import LINK_PROPERTIES_HIDDEN
        from FabrickatorWorkbench.objects.tree import BRICK_GROUP

        f = self.fabrication()
        for brick in fab.bricks(f):   # as saved before the brick group sorted first
            for name in ("PartNumber", "Cell", "Step", "Changed"):
                brick.setGroupOfProperty(name, "Brick")
            for name in LINK_PROPERTIES_HIDDEN:
                brick.setEditorMode(name, 0)
        path = self.path("older.FCStd")
        self.doc.saveAs(path)
        App.closeDocument(self.doc.Name)
        self.doc = App.openDocument(path)
        bricks = fab.bricks(fab.fabrications(self.doc)[0])
        self.assertTrue(bricks)
        for brick in bricks:
            self.assertEqual({brick.getGroupOfProperty(n) for n in ("PartNumber", "Cell", "Step")},
                             {BRICK_GROUP})
            for name in LINK_PROPERTIES_HIDDEN:
                self.assertIn("Hidden", brick.getEditorMode(name), name)
        self.assertEqual([o.Name for o in self.doc.Objects if "Touched" in o.State], [])
