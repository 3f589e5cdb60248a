"""The assembly task panel: step through the build bottom-up, layer by layer.

Step n shows every brick of steps 1..n; the bricks of step n (the ones to
place now) are highlighted in blue, later ones are hidden.  A printed part
appears at the step that inserts it, highlighted, with its ID above it in
the 3D view: white on a dark frame (FreeCAD's ``SoFrameLabel``), drawn over
everything else and sized for the view.  A prop (a stack of 1x1 bricks that
holds an overhang up while it is built) shows as a purple column from the step
it is stood before to the step after which it goes, and the step's words say
where to stand it or that it can go, as the instructions do.  Next / Previous / the slider / Play
move through the steps (step 0 is the empty base).  The high-res regions are
hidden meanwhile.  Closing the panel shows the whole model again exactly as
it was shown before.
"""

from __future__ import annotations

import os

import FreeCADGui as Gui
from pivy import coin
from PySide import QtCore, QtGui

from FabrickatorWorkbench import make
from FabrickatorWorkbench.taskpanels.closing import close_dialog
from FabrickatorWorkbench.taskpanels.titles import fitting_title

#: Colour of the bricks to place in the current step.
NEXT_COLOUR = (0.1, 0.35, 1.0)
#: Size (pixels) of the printed parts' ID labels: a 32nd of the 3D view's height, within
#: these bounds.
LABEL_SIZE_RANGE = (16, 32)
#: Text and frame colour of the ID labels.
LABEL_TEXT = (1.0, 1.0, 1.0)
LABEL_BACKGROUND = (0.08, 0.08, 0.12)
#: Colour and transparency of the props.
PROP_COLOUR = (0.55, 0.3, 0.8)
PROP_TRANSPARENCY = 0.2
#: Milliseconds between steps while playing.
PLAY_INTERVAL_MS = 700

UI = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))),
                  "resources", "ui", "assembly.ui")


class AssemblyPanel:
    """Task panel that steps through the assembly of Fabrication ``fab``."""

    def __init__(self, fab):
        self.fab = fab
        self.doc = fab.Document
        self.steps = make.steps(fab)
        self.warnings, self.props = make.step_notes(fab)
        self.prop_node = None
        self.bricks = [b for b in make.bricks(fab) if b.Kind == "lego"]
        self.parts = make.printed_parts(fab)
        self.by_step: dict[int, list] = {}
        for obj in self.bricks + self.parts:
            self.by_step.setdefault(int(obj.Step), []).append(obj)
        self.shown = {o.Name: bool(o.Visibility) for o in self.bricks + self.parts}
        self.colours = {p.Name: tuple(p.ViewObject.ShapeColor) for p in self.parts}
        self.regions = {r.Name: bool(r.Visibility) for r in fab.Regions}
        for region in fab.Regions:
            region.Visibility = False
        self.highlighted: list = []
        self.labels = None
        self.current = len(self.steps)
        self.form = Gui.PySideUic.loadUi(UI)
        self.form.setWindowTitle(fitting_title("Assembly of ", fab.Label, self.form))
        self.form.setToolTip(f"Assembly of {fab.Label}")
        self.form.slider.setMaximum(len(self.steps))
        self.form.slider.setValue(len(self.steps))
        self.form.slider.valueChanged.connect(self.go)
        self.form.next.clicked.connect(lambda: self.go(self.current + 1))
        self.form.previous.clicked.connect(lambda: self.go(self.current - 1))
        self.form.first.clicked.connect(lambda: self.go(0))
        self.form.last.clicked.connect(lambda: self.go(len(self.steps)))
        self.form.play.toggled.connect(self.on_play)
        self.timer = QtCore.QTimer()
        self.timer.setInterval(PLAY_INTERVAL_MS)
        self.timer.timeout.connect(self.on_tick)
        self.go(1 if self.steps else 0)

    def go(self, step: int) -> None:
        """Show the model as built up to ``step`` (clamped to 0..number of steps)."""
        step = max(0, min(int(step), len(self.steps)))
        before, self.current = self.current, step
        low, high = sorted((before, step))
        for n in range(low, high + 1):
            for obj in self.by_step.get(n, []):
                visible = n <= step
                if bool(obj.Visibility) != visible:
                    obj.Visibility = visible
        self._highlight(step)
        self._show_props(step)
        if self.form.slider.value() != step:
            self.form.slider.blockSignals(True)
            self.form.slider.setValue(step)
            self.form.slider.blockSignals(False)
        self.form.stepLabel.setText(f"Step {step} / {len(self.steps)}")
        self.form.info.setText(self.describe(step))

    def describe(self, step: int) -> str:
        """What to do in ``step``, in words."""
        if step == 0:
            return "Start with an empty base plate."
        s = self.steps[step - 1]
        note = self.warnings.get(str(step))
        note = f"\n{note}" if note else ""
        if s.get("printed_part"):
            return f"Layer {s['layer'] + 1}: insert printed part {s['printed_part']}.{note}"
        counts: dict[str, int] = {}
        for obj in self.by_step.get(step, []):
            counts[obj.PartNumber] = counts.get(obj.PartNumber, 0) + 1
        items = ", ".join(f"{n} x {part}" for part, n in sorted(counts.items()))
        return f"Layer {s['layer'] + 1}: place {items} (blue).{note}"

    def _show_props(self, step: int) -> None:
        """Purple columns for the props standing at ``step`` (replacing earlier ones)."""
        from core.instructions import build_order

        graph = Gui.ActiveDocument.ActiveView.getSceneGraph()
        if self.prop_node is not None:
            graph.removeChild(self.prop_node)
            self.prop_node = None
        standing = [p for p in self.props
                    if p["step"] <= step <= build_order.prop_last_step(p, len(self.steps))]
        if not standing:
            return
        self.prop_node = coin.SoSeparator()
        self.prop_node.setName("FabrickatorAssemblyProps")
        material = coin.SoMaterial()
        material.diffuseColor = PROP_COLOUR
        material.transparency = PROP_TRANSPARENCY
        self.prop_node.addChild(material)
        for prop in standing:
            (x0, y0, z0), (x1, y1, z1) = prop["box_mm"]
            node = coin.SoSeparator()
            move = coin.SoTranslation()
            move.translation = ((x0 + x1) / 2, (y0 + y1) / 2, (z0 + z1) / 2)
            cube = coin.SoCube()
            cube.width, cube.height, cube.depth = x1 - x0, y1 - y0, z1 - z0
            node.addChild(move)
            node.addChild(cube)
            self.prop_node.addChild(node)
        graph.addChild(self.prop_node)

    def _highlight(self, step: int) -> None:
        """Blue for the current step's bricks, the printed part's ID next to it."""
        for obj in self.highlighted:
            self._plain(obj)
        self.highlighted = list(self.by_step.get(step, [])) if step > 0 else []
        for obj in self.highlighted:
            view = obj.ViewObject
            if obj in self.parts:
                view.ShapeColor = NEXT_COLOUR
            else:
                material = view.ShapeMaterial
                material.DiffuseColor = NEXT_COLOUR
                view.ShapeMaterial = material
                view.OverrideMaterial = True
        self._label([o for o in self.highlighted if o in self.parts])

    def _plain(self, obj) -> None:
        if obj in self.parts:
            obj.ViewObject.ShapeColor = self.colours[obj.Name]
        else:
            obj.ViewObject.OverrideMaterial = False

    def _label(self, parts: list) -> None:
        """Write the IDs of ``parts`` above their centres in the 3D view (replacing earlier
        ones): white on a dark frame, over all geometry (an ``SoAnnotation``)."""
        view = Gui.ActiveDocument.ActiveView
        graph = view.getSceneGraph()
        if self.labels is not None:
            graph.removeChild(self.labels)
            self.labels = None
        if not parts:
            return
        self.labels = coin.SoAnnotation()
        self.labels.setName("FabrickatorAssemblyLabels")
        size = label_size(view.getSize()[1])
        for part in parts:
            node = coin.SoSeparator()
            move = coin.SoTranslation()
            box = part.Shape.BoundBox
            move.translation = (box.Center.x, box.Center.y, box.ZMax + 4.0)
            node.addChild(move)
            node.addChild(id_label(part.PartId, size))
            self.labels.addChild(node)
        graph.addChild(self.labels)

    def on_play(self, playing: bool) -> None:
        if playing:
            if self.current >= len(self.steps):
                self.go(0)
            self.timer.start()
        else:
            self.timer.stop()

    def on_tick(self) -> None:
        if self.current >= len(self.steps):
            self.form.play.setChecked(False)
            return
        self.go(self.current + 1)

    def getStandardButtons(self):
        return int(QtGui.QDialogButtonBox.Close)

    def reject(self) -> bool:
        self.finish()
        return True

    def accept(self) -> bool:
        self.finish()
        return True

    def finish(self) -> None:
        """Stop playing, show everything as before and close; the closed panel has no
        form (:func:`.closing.close_dialog`)."""
        self.timer.stop()
        for obj in self.highlighted:
            self._plain(obj)
        self.highlighted = []
        self._label([])
        self._show_props(-1)
        for obj in self.bricks + self.parts:
            if self.doc.getObject(obj.Name) is not None and bool(obj.Visibility) != self.shown[obj.Name]:
                obj.Visibility = self.shown[obj.Name]
        for name, visible in self.regions.items():
            region = self.doc.getObject(name)
            if region is not None and bool(region.Visibility) != visible:
                region.Visibility = visible
        proxy = getattr(getattr(self.fab, "ViewObject", None), "Proxy", None)
        if getattr(proxy, "panel", None) is self:
            proxy.panel = None
        close_dialog(self)


def label_size(view_height: int) -> int:
    """Pixel size of the ID labels in a 3D view ``view_height`` pixels high."""
    low, high = LABEL_SIZE_RANGE
    return max(low, min(high, int(round(view_height / 32))))


def id_label(text: str, size: int):
    """A label node for ``text``: FreeCAD's ``SoFrameLabel``, white text of ``size`` pixels
    on a dark frame, centred on the point where it stands."""
    node = coin.SoType.fromName("SoFrameLabel").createInstance()
    node.set(f'string "{text}" textColor {" ".join(map(str, LABEL_TEXT))} '
             f'backgroundColor {" ".join(map(str, LABEL_BACKGROUND))} '
             f'justification CENTER size {size} frame TRUE')
    return node
