"""GUI tests of how Fabrickator looks in FreeCAD (issue 13): brick colours, edges,
the changed-brick highlight, the tree, the property view and the preferences icon.

Run by ``make test-gui`` (imported at the end of TestFabrickatorGui.py);
screenshots go to tests/gui/artifacts/look_*.png.
"""

from __future__ import annotations


import FreeCAD as App
import FreeCADGui as Gui
import numpy as np
from PySide import QtGui

from TestFabrickatorGui import ARTIFACTS, GuiTestCase, answer_modal, fab, fit, screenshot, settle


def shown_rgb(brick) -> tuple:
    """The colour the 3D view draws ``brick`` in (its prototype's), rounded to 1/255."""
    from FabrickatorWorkbench.objects.prototype import rgb_key

    return rgb_key(brick.LinkedObject.ViewObject.ShapeColor)


def image(path) -> np.ndarray:
    """RGB pixels (h, w, 3) of a PNG file."""
    img = QtGui.QImage(str(path)).convertToFormat(QtGui.QImage.Format_RGB888)
    data = img.constBits()
    rows = np.frombuffer(data, dtype=np.uint8, count=img.bytesPerLine() * img.height())
    return rows.reshape(img.height(), img.bytesPerLine())[:, :img.width() * 3].reshape(
        img.height(), img.width(), 3).astype(int)


def view_colour(name: str, default: int) -> tuple:
    """A colour of FreeCAD's View preferences (RGBA packed in an unsigned) as RGB 0..1."""
    packed = App.ParamGet("User parameter:BaseApp/Preferences/View").GetUnsigned(name, default)
    return tuple(((packed >> shift) & 0xFF) / 255.0 for shift in (24, 16, 8))


class TestLook(GuiTestCase):
    def test_bricks_show_the_colour_the_bom_orders_with_their_edges(self):
        from core import colours
        from FabrickatorWorkbench.objects.prototype import rgb_key

        f = self.fabrication(high_res=(0, 0, 12.8, 8, 8, 19.2))
        fab().clear_changes(f)      # marking the region highlighted the bricks it changed
        settle()
        lego = [b for b in fab().bricks(f) if b.Kind == "lego"]
        grey = rgb_key(colours.rgb(colours.BOM_COLOR))
        self.assertEqual({shown_rgb(b) for b in lego}, {grey})
        for proto in {b.LinkedObject for b in lego}:
            self.assertEqual(proto.ViewObject.DisplayMode, "Flat Lines")
        pixels = image(screenshot("look_bom_colours"))
        dark = (pixels.max(axis=-1) < 70).sum()   # the edges FreeCAD draws on grey bricks
        bricks = (np.abs(pixels - pixels[:, :, :1]).max(axis=-1) < 12) & (pixels[:, :, 0] < 235)
        self.assertGreater(bricks.sum(), 5000)      # grey, shaded brick faces
        self.assertGreater(dark, 0.02 * bricks.sum(), "brick edges are not drawn")

    def test_example_in_bom_colours(self):
        f = self.open_example()
        self.assertTrue(f.Status.startswith("ok"), f.Status)
        self.assertEqual(len({shown_rgb(b) for b in fab().bricks(f) if b.Kind == "lego"}), 1)
        screenshot("look_example_bom_colours")

    def test_random_colours_preference_colours_bricks_apart_and_back(self):
        from core import colours
        from FabrickatorWorkbench import preferences
        from FabrickatorWorkbench.objects.prototype import rgb_key

        preferences.set("Palette", "random")
        f = self.fabrication()
        random = {rgb_key(colours.rgb(c)) for c in colours.RANDOM_CODES}
        seen = {shown_rgb(b) for b in fab().bricks(f)}
        self.assertLessEqual(seen, random)
        self.assertGreater(len(seen), 3)
        screenshot("look_random_colours")
        preferences.reset("Palette")
        f.touch()
        self.doc.recompute()
        settle()
        self.assertEqual({shown_rgb(b) for b in fab().bricks(f)},
                         {rgb_key(colours.rgb(colours.BOM_COLOR))})

    def test_highlight_is_distinct_from_selection_preselection_and_bricks(self):
        from core import colours
        from FabrickatorWorkbench.objects.prototype import HIGHLIGHT_COLOUR
        from FabrickatorWorkbench.viewproviders.brick import GHOST_COLOUR
        from FabrickatorWorkbench.viewproviders.printed_part import PRINTED_COLOUR

        selection = view_colour("SelectionColor", 0x1CAD1CFF)
        preselection = view_colour("HighlightColor", 0xE1E114FF)
        self.assertGreater(colours.delta_e(HIGHLIGHT_COLOUR, selection), 50)
        self.assertGreater(colours.delta_e(HIGHLIGHT_COLOUR, preselection), 50)
        bricks = [colours.rgb(c) for c in colours.RANDOM_CODES + (colours.BOM_COLOR,
                                                                  colours.PRINTED_COLOR)]
        for other in bricks + [PRINTED_COLOUR, GHOST_COLOUR]:
            self.assertGreater(colours.delta_e(HIGHLIGHT_COLOUR, other), 40, other)

    def test_prototypes_stay_out_of_the_tree_and_in_the_document(self):
        from FabrickatorWorkbench.objects import tree

        f = self.fabrication()
        group = next(o for o in self.doc.Objects if tree.role(o) == tree.PROTOTYPES_ROLE)
        self.assertFalse(group.ViewObject.ShowInTree)
        settle()
        labels = [item.text(0) for w in Gui.getMainWindow().findChildren(QtGui.QTreeWidget)
                  for item in w.findItems("*", QtCore_match_flags(), 0) if shown_in_tree(item)]
        self.assertIn(f.Label, labels)
        self.assertFalse([t for t in labels if "prototype" in t.lower()], labels)
        self.assertTrue(tree.prototypes(self.doc))
        f.BrickSet = "plates"      # a recompute finds the group and adds to it
        self.doc.recompute()
        self.assertTrue(f.Status.startswith("ok"), f.Status)
        groups = [o for o in self.doc.Objects if tree.role(o) == tree.PROTOTYPES_ROLE]
        self.assertEqual(len(groups), 1)
        self.assertFalse(groups[0].ViewObject.ShowInTree)
        fab().remove_owned(f)       # deleting the Fabrication finds it too
        self.assertEqual([o for o in self.doc.Objects
                          if tree.role(o) in (tree.PROTOTYPES_ROLE, "Prototype")], [])

    def test_brick_properties_come_first_in_the_property_view(self):
        f = self.fabrication()
        brick = fab().bricks(f)[0]
        Gui.Selection.clearSelection()
        Gui.Selection.addSelection(brick)
        settle(0.3)
        groups = property_view_groups()
        self.assertEqual(groups[0][0].strip(), "Brick", groups)
        names = [n for _, shown in groups for n in shown]
        self.assertLess(names.index("Part Number"), names.index("Linked Object"), names)
        for hidden in ("Link Copy On Change", "Show Element", "Scale", "Placement List"):
            self.assertNotIn(hidden, names)
        Gui.Selection.clearSelection()

    def test_preferences_page_has_its_icon_and_the_palette(self):
        from FabrickatorWorkbench import preferences

        found = {}

        def handler(dialog):
            box = dialog.findChild(QtGui.QListWidget, "listBox")
            if box is not None:   # FreeCAD 0.20: a list of groups
                items = [box.item(i) for i in range(box.count())]
                icons = {i.text(): i.icon() for i in items}
            else:                 # FreeCAD 1.x: a tree of groups and pages
                view = dialog.findChild(QtGui.QTreeView, "groupsTreeView")
                model = view.model()
                icons = {model.index(r, 0).data(): model.index(r, 0).data(1)
                         for r in range(model.rowCount())}
            found["icon"] = icons.get("Fabrickator")
            combo = dialog.findChild(QtGui.QComboBox, "palette")
            found["palette"] = combo.currentText()
            combo.setCurrentIndex(combo.findData("random"))
            ARTIFACTS.mkdir(parents=True, exist_ok=True)
            dialog.grab().save(str(ARTIFACTS / "look_preferences.png"))
            dialog.accept()

        answer_modal(handler, "Gui__Dialog__DlgPreferences")
        Gui.showPreferences("Fabrickator", 0)
        settle()
        icon = found["icon"]
        self.assertIsNotNone(icon)
        self.assertFalse(icon.isNull())
        # FreeCAD 1.x gives the 24 px size it holds when asked for 48: count what is drawn
        picture = icon.pixmap(48, 48).toImage()
        width, height = picture.width(), picture.height()
        self.assertGreaterEqual(min(width, height), 16)
        opaque = sum(1 for x in range(width) for y in range(height)
                     if QtGui.QColor.fromRgba(picture.pixel(x, y)).alpha() > 128)
        self.assertGreater(opaque / (width * height), 0.15)  # the brick drawing, not an empty square
        self.assertEqual(found["palette"], "BOM colours")
        self.assertEqual(preferences.get("Palette"), "random")
        self.assertEqual(preferences.palette(), "random")


def shown_in_tree(item) -> bool:
    """Whether a tree view item shows: neither it nor an item above it is hidden."""
    while item is not None:
        if item.isHidden():
            return False
        item = item.parent()
    return True


def QtCore_match_flags():
    """Match every item of a tree widget, at any depth."""
    from PySide import QtCore

    return QtCore.Qt.MatchWildcard | QtCore.Qt.MatchRecursive


def property_view_groups() -> list[tuple[str, list[str]]]:
    """The groups of FreeCAD's property view (Data tab) in the order shown, each with the
    names of the properties it shows."""
    editors = [w for w in Gui.getMainWindow().findChildren(QtGui.QTreeView)
               if w.metaObject().className() == "Gui::PropertyEditor::PropertyEditor"]

    def groups(editor):
        model = editor.model()
        out = []
        for r in range(model.rowCount()):
            group = model.index(r, 0)
            out.append((str(group.data()), [str(model.index(c, 0, group).data())
                                            for c in range(model.rowCount(group))]))
        return out

    seen = [groups(e) for e in editors]
    # the Data tab's editor (the View tab's shows the view provider's properties, no Label)
    data = [g for g in seen if any("Label" in names for _, names in g)]
    assert data, f"no property view shows a Label: {seen}"
    return data[0]
