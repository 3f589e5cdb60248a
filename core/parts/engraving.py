"""The part's id engraved into a flat outer side, where it fits and stays whole.

:func:`engrave_id` tries the outer sides of the part's bricks, largest text first, and cuts
the id :data:`ENGRAVE_DEPTH_MM` deep where the side is flat, uncovered and leaves
:data:`ENGRAVE_KEEP_MM` of wall behind the letters, or says why it could not.
:func:`text_shape` sets the text (DejaVu Sans Bold through cadquery, with the system's
fontconfig so OpenCascade prints no fontconfig error); the calibration strip engraves with it
too.  The side is vertical, so in an upright print it faces sideways.
"""

from __future__ import annotations

import os
from typing import TYPE_CHECKING

import manifold3d as m3
import numpy as np

from core.model import Brick
from core.parts.booleans import InvalidSolid, as_manifold, cube, finished, occ_volume
from core.parts.interfaces import Fit
from core.parts.printed_part import PrintedPart

if TYPE_CHECKING:  # OpenCascade and cadquery are imported where B-rep parts are made
    import cadquery as cq
    from OCP.TopoDS import TopoDS_Shape


#: Depth (mm) of the engraved part id.
ENGRAVE_DEPTH_MM = 0.5
#: Wall (mm) that must stay behind the engraved letters.
ENGRAVE_KEEP_MM = 0.4
#: Free border (mm) around the text on its side face.
ENGRAVE_MARGIN_MM = 0.4
#: Font sizes (mm) tried for the id, largest first.
ENGRAVE_FONT_SIZES = (5.0, 4.0, 3.0, 2.5)
#: How far (mm) the cutting text starts outside the face (no coplanar Boolean faces).
ENGRAVE_OVERSHOOT_MM = 0.2
#: Steps (mm) in which the id is moved along a side when its centre is covered or not whole.
ENGRAVE_STEP_MM = 4.0
#: Free space (mm) the engraved side must have in front of it (else the side is covered).
ENGRAVE_CLEAR_MM = 1.0
#: The font of the id (DejaVu Sans Bold, Debian fonts-dejavu-core).
ENGRAVE_FONT = "/usr/share/fonts/truetype/dejavu/DejaVuSans-Bold.ttf"
#: The system's fontconfig configuration, given to OpenCascade's bundled fontconfig.
SYSTEM_FONTS_CONF = "/etc/fonts/fonts.conf"


def engrave_id(part: PrintedPart, bricks: list[Brick], grid, mine: np.ndarray, other: np.ndarray,
             fit: Fit, engine) -> None:
    """Cut the part id ENGRAVE_DEPTH_MM deep into a flat vertical side where it fits.

    Candidates are the outer sides of the part's bricks (sides that do not
    face another brick of the part): those that take the largest text
    first, then those that face other bricks (a face the envelope cut, not
    one the designer drew; hidden once built), then the largest.  For each,
    the biggest of ENGRAVE_FONT_SIZES whose text (plus ENGRAVE_MARGIN_MM)
    fits the side is placed centred on it (else moved along it, then to its
    top or bottom: :func:`_positions`), and a place is taken only when
    the slab behind the text, ENGRAVE_DEPTH_MM + ENGRAVE_KEEP_MM deep, lies
    wholly inside the part and the slab ENGRAVE_CLEAR_MM in front of it
    holds nothing of the part: then the part has a flat, uncovered side
    there and at least ENGRAVE_KEEP_MM of wall stays behind the letters.  The side is
    vertical, so in an upright print it faces sideways.  Sets ``engraved``,
    ``engraving`` (where, or why not) and updates the part's solid, mesh and
    volume.
    """
    from core.parts.brick_solids import SIDE_TAGS, to_trimesh
    sizes = {f: _text_size(part.id, f) for f in ENGRAVE_FONT_SIZES}
    candidates = []
    for b in bricks:
        for side in SIDE_TAGS:
            face = _side_face(b, side, grid, mine, other, fit)
            if face is None:
                continue
            fits = [f for f in ENGRAVE_FONT_SIZES
                    if sizes[f][0] + 2 * ENGRAVE_MARGIN_MM <= face["width"]
                    and sizes[f][1] + 2 * ENGRAVE_MARGIN_MM <= face["height"]]
            if fits:
                candidates.append((-max(fits), -face["hidden"], -face["width"] * face["height"],
                                   b.id, SIDE_TAGS.index(side), face, max(fits)))
    candidates.sort(key=lambda c: c[:5])
    inside = _inside_test(part)
    body = as_manifold(part.mesh)
    for *_, side, font in candidates:
        width, height = sizes[font]
        behind = ENGRAVE_DEPTH_MM + ENGRAVE_KEEP_MM
        for face in _positions(side, width + 2 * ENGRAVE_MARGIN_MM, height + 2 * ENGRAVE_MARGIN_MM):
            if not inside(_slab(face, width + 2 * ENGRAVE_MARGIN_MM, height + 2 * ENGRAVE_MARGIN_MM, behind)):
                continue
            front = _slab(face, width + 2 * ENGRAVE_MARGIN_MM, height + 2 * ENGRAVE_MARGIN_MM, -ENGRAVE_CLEAR_MM)
            if (body ^ cube(*front)).volume() <= 1e-6 * np.prod(front[1] - front[0]):
                break
        else:
            continue
        text = _text_solid(part.id, font, face)
        try:
            body = part.solid if part.solid is not None else as_manifold(part.mesh)
            tool = text if part.solid is not None else as_manifold(to_trimesh(text))
            solid, mesh = finished(engine, engine.cut(body, [tool]), part.id, rounds=0)
            if part.solid is not None:
                part.solid = solid
            part.mesh, part.volume_mm3 = mesh, engine.volume(solid)
        except InvalidSolid:
            continue
        part.engraved = True
        part.engraving = {"brick": face["brick"], "side": face["side"],
                          "centre_mm": [round(float(v), 4) for v in face["centre"]],
                          "normal": [float(v) for v in face["normal"]],
                          "text_mm": [round(width, 3), round(height, 3)],
                          "font_size_mm": font, "depth_mm": ENGRAVE_DEPTH_MM}
        return
    part.engraving = ("not engraved: no outer flat side large enough for the id"
                      if not candidates else
                      "not engraved: no outer side large enough stays whole")


def _side_face(b: Brick, side: str, grid, mine: np.ndarray, other: np.ndarray, fit: Fit) -> dict | None:
    """The outer side ``side`` of brick ``b`` as a plane rectangle: centre, outward
    normal, horizontal reading direction, width and height (mm), and ``hidden``,
    the fraction of the cells across it that other bricks fill; None when
    every cell across belongs to the part."""
    i, j, k = b.cell
    sx, sy, sz = b.size
    axis = 0 if side[-1] == "x" else 1
    sign = 1 if side[-2] == "+" else -1
    nx, ny, _ = mine.shape
    if axis == 0:
        at = i + sx if sign > 0 else i - 1
        span = (slice(at, at + 1), slice(j, j + sy), slice(k, k + sz)) if 0 <= at < nx else None
    else:
        at = j + sy if sign > 0 else j - 1
        span = (slice(i, i + sx), slice(at, at + 1), slice(k, k + sz)) if 0 <= at < ny else None
    if span is not None and mine[span].all():
        return None
    hidden = float(other[span].mean()) if span is not None else 0.0
    lo = np.asarray(grid.origin) + np.array(b.cell) * grid.cell
    hi = lo + np.array(b.size) * grid.cell
    lo[:2] += fit.play
    hi[:2] -= fit.play
    centre = (lo + hi) / 2
    boundary = (hi[axis] + fit.play) if sign > 0 else (lo[axis] - fit.play)
    centre[axis] = boundary - sign * (fit.play if hidden > 0 else 0.0)
    normal = np.zeros(3)
    normal[axis] = sign
    return {"brick": b.id, "side": side, "centre": centre, "normal": normal, "hidden": hidden,
            "right": np.cross([0.0, 0.0, 1.0], normal),
            "width": float(hi[1 - axis] - lo[1 - axis]), "height": float(hi[2] - lo[2])}


def _font_path() -> str | None:
    """The bundled-with-Debian DejaVu Sans Bold font when present (else cadquery's default)."""
    return ENGRAVE_FONT if os.path.exists(ENGRAVE_FONT) else None


def _use_system_fontconfig() -> None:
    """Point OpenCascade's fontconfig at the system's ``fonts.conf`` unless the user set one.

    The fontconfig library bundled with the cadquery-ocp wheel was built
    with its configuration folder inside the build machine's conda
    environment (``/usr/share/miniconda3/envs/cadquery-ocp/etc/fonts``), so
    on any other machine the first text shape prints "Fontconfig error:
    Cannot load default config file" on stderr.  Fontconfig reads
    ``FONTCONFIG_FILE`` when OpenCascade's font manager first initialises
    it, so setting it before the first text shape is enough.  Nothing
    changes when ``FONTCONFIG_FILE`` or ``FONTCONFIG_PATH`` is already set
    or the system has no :data:`SYSTEM_FONTS_CONF`.
    """
    if not {"FONTCONFIG_FILE", "FONTCONFIG_PATH"} & set(os.environ) and os.path.exists(SYSTEM_FONTS_CONF):
        os.environ["FONTCONFIG_FILE"] = SYSTEM_FONTS_CONF


def text_shape(text: str, font: float, plane: cq.Plane, distance: float) -> cq.Shape:
    """``text`` at ``font`` size, DejaVu Sans Bold, centred at the plane's origin,
    extruded ``distance`` along the plane's normal (negative: into the part)."""
    import cadquery as cq
    _use_system_fontconfig()
    kwargs = {"fontPath": _font_path()} if _font_path() else {}
    return cq.Workplane(plane).text(text, font, distance, combine=False, halign="center",
                                    valign="center", kind="bold", **kwargs).val()


def _text_size(text: str, font: float) -> tuple[float, float]:
    """Width and height (mm) of ``text`` set at ``font`` size."""
    import cadquery as cq
    box = text_shape(text, font, cq.Plane.XY(), 1.0).BoundingBox()
    return float(box.xlen), float(box.ylen)


def _text_solid(text: str, font: float, face: dict) -> TopoDS_Shape:
    """The cutting tool of the engraving: ``text`` centred on ``face``, from
    ENGRAVE_OVERSHOOT_MM outside it to ENGRAVE_DEPTH_MM into the part."""
    import cadquery as cq
    start = face["centre"] + ENGRAVE_OVERSHOOT_MM * face["normal"]
    shape = text_shape(text, font, cq.Plane(origin=tuple(start), xDir=tuple(face["right"]),
                                             normal=tuple(face["normal"])),
                        -(ENGRAVE_DEPTH_MM + ENGRAVE_OVERSHOOT_MM))
    box = shape.BoundingBox()
    shift = face["centre"] - np.array([box.center.x, box.center.y, box.center.z])
    shift -= np.dot(shift, face["normal"]) * face["normal"]
    return shape.translate(cq.Vector(*shift)).wrapped


def _positions(face: dict, width: float, height: float):
    """``face`` with its centre moved to where a ``width`` x ``height`` text box may sit on
    it: the centre first, then along the side in steps of :data:`ENGRAVE_STEP_MM` (and to
    the ends), then also to its top and bottom; the box always stays on the side."""
    along = max((face["width"] - width) / 2, 0.0)
    up = max((face["height"] - height) / 2, 0.0)
    shifts = np.unique(np.round(np.concatenate(
        [np.arange(0.0, along, ENGRAVE_STEP_MM), [along]]), 6))
    offsets = sorted({(sign * a, v) for a in shifts for sign in (1, -1) for v in (0.0, up, -up)},
                     key=lambda o: (o[1] != 0.0, abs(o[0]), o[0] < 0, o[1] < 0))
    right = np.abs(face["right"])
    for a, v in offsets:
        yield dict(face, centre=face["centre"] + right * a + np.array([0.0, 0.0, v]))


def _slab(face: dict, width: float, height: float, depth: float) -> np.ndarray:
    """(2, 3) min/max corners of the box of ``width`` x ``height`` centred on ``face``,
    reaching ``depth`` behind it into the part."""
    right, normal = np.abs(face["right"]), face["normal"]
    half = right * width / 2 + np.array([0.0, 0.0, height / 2])
    a = face["centre"] - half
    b = face["centre"] + half - normal * depth
    return np.stack([np.minimum(a, b), np.maximum(a, b)])


def _inside_test(part: PrintedPart):
    """A function telling whether a box ((2, 3) corners) lies wholly inside the part.

    Mesh parts: a manifold3d difference (milliseconds).  B-rep parts: a
    grid of points in the box is classified first (a cheap rejection) and a
    box that passes is confirmed with an OCC Boolean on the exact solid.
    """
    if part.solid is None:
        solid = as_manifold(part.mesh)

        def inside_mesh(box: np.ndarray) -> bool:
            tool = m3.Manifold.cube(list(box[1] - box[0])).translate(list(box[0]))
            return (tool - solid).volume() <= 1e-6 * np.prod(box[1] - box[0])
        return inside_mesh
    from OCP.BRepClass3d import BRepClass3d_SolidClassifier
    from OCP.gp import gp_Pnt
    from OCP.TopAbs import TopAbs_IN
    classifier = BRepClass3d_SolidClassifier(part.solid)

    def inside_brep(box: np.ndarray) -> bool:
        inset = np.minimum(0.05, (box[1] - box[0]) / 4)
        axes = [np.linspace(a, b, 4) for a, b in zip(box[0] + inset, box[1] - inset)]
        for point in np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3):
            classifier.Perform(gp_Pnt(*point), 1e-6)
            if classifier.State() != TopAbs_IN:
                return False
        return _inside_brep(part.solid, box)
    return inside_brep


def _inside_brep(shape: TopoDS_Shape, box: np.ndarray) -> bool:
    """True when the box ((2, 3) corners) lies wholly inside the OCC solid ``shape``."""
    from OCP.BRepAlgoAPI import BRepAlgoAPI_Cut
    from OCP.BRepPrimAPI import BRepPrimAPI_MakeBox
    from OCP.gp import gp_Pnt
    tool = BRepPrimAPI_MakeBox(gp_Pnt(*box[0]), gp_Pnt(*box[1])).Shape()
    outside = BRepAlgoAPI_Cut(tool, shape)
    if not outside.IsDone():
        return False
    return occ_volume(outside.Shape()) <= 1e-6 * np.prod(box[1] - box[0])
