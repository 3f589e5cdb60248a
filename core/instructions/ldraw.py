"""LDraw: the assembly as a model that LeoCAD, LDView, BrickLink Studio and LPub3D read.

Conventions (LDraw file format 1.0.2 and the official parts library):

* 1 LDU = 0.4 mm: stud pitch 20 LDU, plate 8 LDU, brick 24 LDU; -Y is up.  A model point
  (x, y, z) in mm (z up) goes to LDraw (x, -z, y) / 0.4, a proper rotation, so nothing is
  mirrored.  The grid origin goes to LDraw y = 0 (the model stands on the plane y = 0), and
  x and z are shifted by whole studs so that the model's footprint is centred on the origin.
* A part file's origin is the top centre of its body (studs excluded), the body hangs down
  to y = 8 (plate) or 24 (brick), and its long side runs along X (3001 spans x -40..40,
  z -20..20).  A brick turned by 90° (long side along the model's y) gets the rotation
  that takes X to Z.
* Colours: those the bill of materials orders (:func:`core.colours.ordered_code`, whatever
  the display palette): LEGO bricks :data:`LEGO_COLOR` (71, Light Bluish Grey, the neutral
  colour of most LEGO construction sets), printed parts :data:`PRINTED_COLOR` (25, Orange).

The file is an MPD (``assembly.mpd``): the main model with one line-type-1 reference per
LEGO brick and ``0 STEP`` between the assembly steps, then one embedded subfile per printed
part (``0 FILE printed_P1.ldr``) holding its triangles (line type 3, colour 16), referenced
once, in its step, with the identity transform (its coordinates are already in place).
The build's props (:attr:`core.instructions.build_order.BuildOrder.props`) are in the step they are stood
in, each after a comment that says what it holds; one taken away later carries LeoCAD's
``0 !LEOCAD PIECE STEP_HIDE <step>`` (the first step it is gone in), which LeoCAD honours
and other programs ignore, showing it to the end.

:func:`parse` reads such a file back (any LDraw/MPD text with line types 0-5), and
:func:`placed_bricks` turns the references back into grid cells, so the writer is checked
by a round trip.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from core import colours
from core.catalog import BY_NUMBER
from core.errors import InputError
from core.model import Layout

#: mm per LDraw unit.
LDU_MM = 0.4
#: LDU per stud and per plate layer.
STUD_LDU = 20
PLATE_LDU = 8
#: LDraw colour of LEGO bricks and of printed parts (decided by :mod:`core.colours`:
#: the colours the bill of materials orders), and the inherit colour.
LEGO_COLOR = colours.BOM_COLOR
PRINTED_COLOR = colours.PRINTED_COLOR
#: LDraw colour of the props' parts: the one the bill of materials orders them in.
PROP_COLOR = colours.BOM_COLOR
MAIN_COLOR = 16
#: LDraw colour code -> (LDraw name, BrickLink colour id, BrickLink name, RGB hex).
COLORS = colours.COLORS
#: Rotation taking a part's long side (X) to the model's y (LDraw Z).
TURNED = np.array([[0, 0, -1], [0, 1, 0], [1, 0, 0]])
#: Name of the main model inside the MPD.
MAIN_NAME = "assembly.ldr"


def color_name(code: int) -> str:
    """LDraw name of colour ``code`` (one of :data:`COLORS`)."""
    return colours.name(code)


def subfile_name(part_id: str) -> str:
    """Name of the embedded subfile of printed part ``part_id``."""
    return f"printed_{part_id}.ldr"


def model_to_ldu(points_mm: np.ndarray, origin_mm, shift_ldu) -> np.ndarray:
    """LDraw coordinates (..., 3) of model points in mm (see the module docstring)."""
    p = (np.asarray(points_mm, dtype=float) - np.asarray(origin_mm, dtype=float)) / LDU_MM
    return np.stack([p[..., 0] - shift_ldu[0], -p[..., 2], p[..., 1] - shift_ldu[1]], axis=-1)


def ldu_to_model(points_ldu: np.ndarray, origin_mm, shift_ldu) -> np.ndarray:
    """Inverse of :func:`model_to_ldu`: model mm (..., 3) of LDraw points."""
    q = np.asarray(points_ldu, dtype=float)
    p = np.stack([q[..., 0] + shift_ldu[0], q[..., 2] + shift_ldu[1], -q[..., 1]], axis=-1)
    return p * LDU_MM + np.asarray(origin_mm, dtype=float)


def centring_shift(shape) -> tuple[int, int]:
    """LDU shift (x, z) that centres a grid of ``shape`` cells on the origin, whole studs."""
    return STUD_LDU * (int(shape[0]) // 2), STUD_LDU * (int(shape[1]) // 2)


def brick_placement(cell, size, shift_ldu) -> tuple[np.ndarray, np.ndarray]:
    """(position (3,), rotation (3, 3)) of a brick at ``cell`` with ``size`` in LDU."""
    i, j, k = (int(c) for c in cell)
    sx, sy, sz = (int(s) for s in size)
    pos = np.array([STUD_LDU * i + STUD_LDU * sx / 2 - shift_ldu[0],
                    -PLATE_LDU * (k + sz),
                    STUD_LDU * j + STUD_LDU * sy / 2 - shift_ldu[1]])
    rot = TURNED if sy > sx else np.eye(3, dtype=int)
    return pos, rot


def _num(v: float) -> str:
    """A coordinate as LDraw text: integers plain, else up to 3 decimals."""
    r = round(float(v), 3)
    if r == int(r):
        return str(int(r))
    return f"{r:.3f}".rstrip("0").rstrip(".")


def _ref(color: int, pos, rot, name: str) -> str:
    nums = [_num(v) for v in pos] + [_num(v) for v in np.asarray(rot).ravel()]
    return f"1 {color} {' '.join(nums)} {name}"


def _triangles(mesh, origin_mm, shift_ldu) -> list[str]:
    """Line-type-3 lines of a trimesh in LDraw coordinates (one formatted block)."""
    tri = model_to_ldu(np.asarray(mesh.vertices)[np.asarray(mesh.faces)], origin_mm, shift_ldu)
    # to 3 decimals without trailing zeros (%g of the rounded value; + 0.0 makes -0 zero)
    flat = np.round(tri.reshape(-1, 9), 3) + 0.0
    row = "3 16 " + " ".join(["%.12g"] * 9)
    return [row % tuple(values) for values in flat.tolist()]


def _prop_lines(prop: dict, shift_ldu) -> list[str]:
    """The lines of one prop: a comment, then its parts from the table up (plates first),
    each after LeoCAD's STEP_HIDE when the prop is taken away after a step."""
    i, j, _ = (int(c) for c in prop["cell"])
    after = prop.get("removed_after")
    lines = [f"0 // prop under brick {prop['under']}: stand it before this step; "
             + (f"take it away after step {after}" if after is not None else "it stays")]
    z = 0
    for number in sorted(prop["parts"], key=lambda n: BY_NUMBER[n].layers):
        layers = BY_NUMBER[number].layers
        for _ in range(int(prop["parts"][number])):
            pos, rot = brick_placement((i, j, z), (1, 1, layers), shift_ldu)
            if after is not None:
                lines.append(f"0 !LEOCAD PIECE STEP_HIDE {int(after) + 1}")
            lines.append(_ref(PROP_COLOR, pos, rot, f"{number}.dat"))
            z += layers
    return lines


def write(layout: Layout, printed_parts, steps, path: str | os.PathLike, title: str = "",
          props=(), codes: dict | None = None) -> Path:
    """Write ``layout`` as an MPD file at ``path``; returns the path.

    ``steps`` is a list of brick-id lists (or :class:`core.instructions.build_order.Step`
    objects), one per assembly step, covering every brick once;
    ``printed_parts`` are :class:`core.parts.printed_part.PrintedPart` s (their ``mesh``
    in model mm).  Each step's LEGO bricks become type-1 references to
    ``<design number>.dat`` in :data:`LEGO_COLOR`; a printed part becomes one
    reference to its embedded subfile, in the step of its first brick.
    ``props`` (:attr:`core.instructions.build_order.BuildOrder.props`) go into the step each is stood
    before (see the module's text).  ``codes`` (brick id -> LDraw colour) colours the LEGO
    bricks instead (a maker's own bricks, :func:`core.inventory.colour`).
    Raises ValueError when a brick is in no step or in two, a step names a
    brick that is not in the layout, or a printed brick has no printed part
    (the caller's steps and parts do not match the layout).
    """
    grid = layout.grid
    shift = centring_shift(grid.shape)
    index = {b.id: b for b in layout.bricks}
    meshes = {p.id: p.mesh for p in printed_parts}
    seen: set[int] = set()
    lines = [f"0 FILE {MAIN_NAME}",
             f"0 {title or 'Fabrickator assembly'}",
             f"0 Name: {MAIN_NAME}",
             "0 Author: Fabrickator",
             "0 // 1 LDU = 0.4 mm, -Y up; LEGO bricks colour 71 (Light Bluish Grey), "
             "printed parts colour 25 (Orange) as embedded subfiles" if codes is None else
             "0 // 1 LDU = 0.4 mm, -Y up; LEGO bricks in the colours of your inventory, "
             "printed parts colour 25 (Orange) as embedded subfiles",
             ""]
    step_lists = [list(getattr(s, "bricks", s)) for s in steps]
    inserted: set[str] = set()
    for n, bricks in enumerate(step_lists):
        if n:
            lines.append("0 STEP")
        for prop in props:
            if prop["step"] == n + 1:
                lines += _prop_lines(prop, shift)
        for bid in bricks:
            b = index.get(bid)
            if b is None or bid in seen:
                raise ValueError(f"step {n + 1} lists brick {bid}, which is not in the layout "
                                 "or already in an earlier step")
            seen.add(bid)
            if b.kind == "printed":
                if b.printed_part not in meshes:
                    raise ValueError(f"brick {bid} is printed but its printed part "
                                     f"{b.printed_part!r} was not given")
                if b.printed_part not in inserted:
                    inserted.add(b.printed_part)
                    lines.append(_ref(colours.ordered_code(b), (0, 0, 0), np.eye(3, dtype=int),
                                      subfile_name(b.printed_part)))
                continue
            pos, rot = brick_placement(b.cell, b.size, shift)
            code = colours.ordered_code(b) if codes is None else codes[b.id]
            lines.append(_ref(code, pos, rot, f"{b.part}.dat"))
    missing = [b.id for b in layout.bricks if b.id not in seen]
    if missing:
        raise ValueError(f"{len(missing)} brick(s) are in no assembly step (e.g. {missing[:5]})")
    if step_lists:
        lines.append("0 STEP")
    lines.append("0 NOFILE")
    for p in printed_parts:
        name = subfile_name(p.id)
        lines += ["", f"0 FILE {name}", f"0 Printed part {p.id}", f"0 Name: {name}",
                  "0 Author: Fabrickator", "0 BFC CERTIFY CCW"]
        lines += _triangles(p.mesh, grid.origin, shift)
        lines.append("0 NOFILE")
    path = Path(path)
    path.write_text("\r\n".join(lines) + "\r\n", encoding="utf-8")
    return path


@dataclass
class Reference:
    """A line-type-1 reference: colour, position (3,), rotation (3, 3), file name."""

    color: int
    position: np.ndarray
    rotation: np.ndarray
    name: str
    #: LeoCAD's ``0 !LEOCAD PIECE STEP_HIDE``: the first step the part is gone in (None: never)
    step_hide: int | None = None


@dataclass
class LDrawFile:
    """One (sub)file: its references per step and its triangles (n, 3, 3) in LDU."""

    name: str
    steps: list[list[Reference]] = field(default_factory=lambda: [[]])
    triangles: np.ndarray = field(default_factory=lambda: np.zeros((0, 3, 3)))
    quads: int = 0
    lines: int = 0
    bfc_ccw: bool = False


@dataclass
class LDrawDocument:
    """A parsed LDraw or MPD text: its files in order, the first is the main model."""

    files: dict[str, LDrawFile]

    @property
    def main(self) -> LDrawFile:
        return next(iter(self.files.values()))

    def embedded(self, name: str) -> LDrawFile | None:
        """The embedded subfile called ``name`` (case-insensitive), or None."""
        for key, f in self.files.items():
            if key.lower() == name.lower():
                return f
        return None


_COUNTS = {1: 15, 2: 8, 3: 11, 4: 14, 5: 14}


def parse(text_or_path) -> LDrawDocument:
    """Parse LDraw / MPD text (or a file path) into its files, steps and geometry.

    Line types: 0 (``FILE``, ``NOFILE``, ``STEP``, ``BFC CERTIFY CCW``, LeoCAD's
    ``!LEOCAD PIECE STEP_HIDE`` for the next reference; other meta lines and
    comments are skipped), 1 (references), 2-5 (geometry;
    triangles are kept, quads counted).  A trailing empty step is dropped.
    LDraw text is a file the user may give (from LeoCAD, Studio, ...), so it
    raises InputError naming the line for an unknown line type, a wrong
    number of fields, a number that does not parse or is not finite, a
    singular rotation, or geometry outside any file of an MPD.
    """
    if isinstance(text_or_path, (str, os.PathLike)) and "\n" not in str(text_or_path) \
            and Path(text_or_path).is_file():
        text = Path(text_or_path).read_text(encoding="utf-8", errors="replace")
    else:
        text = str(text_or_path)
    files: dict[str, LDrawFile] = {}
    current: LDrawFile | None = None
    tris: dict[str, list] = {}
    step_hide = None
    for number, raw in enumerate(text.splitlines(), start=1):
        tokens = raw.split()
        if not tokens:
            continue
        kind = tokens[0]
        if kind == "0":
            word = tokens[1].upper() if len(tokens) > 1 else ""
            if word == "FILE":
                name = raw.split(None, 2)[2].strip() if len(tokens) > 2 else f"file{len(files)}"
                current = files[name] = LDrawFile(name)
                tris[name] = []
            elif word == "NOFILE":
                current = None
            elif word == "STEP" and current is not None:
                current.steps.append([])
            elif word == "BFC" and current is not None and "CCW" in (t.upper() for t in tokens[2:]):
                current.bfc_ccw = True
            elif [t.upper() for t in tokens[1:4]] == ["!LEOCAD", "PIECE", "STEP_HIDE"] and len(tokens) > 4:
                try:
                    step_hide = int(tokens[4])
                except ValueError:
                    raise InputError(f"LDraw line {number}: STEP_HIDE needs a step number: {raw.strip()!r}")
            continue
        if kind not in ("1", "2", "3", "4", "5"):
            raise InputError(f"LDraw line {number}: unknown line type {kind!r}")
        if current is None:
            if files:
                raise InputError(f"LDraw line {number}: geometry outside any 0 FILE block")
            current = files["main"] = LDrawFile("main")
            tris["main"] = []
        t = int(kind)
        if (t == 1 and len(tokens) < 15) or (t != 1 and len(tokens) != _COUNTS[t]):
            raise InputError(f"LDraw line {number}: line type {t} needs {_COUNTS[t]} fields, "
                             f"got {len(tokens)}")
        try:
            values = [float(v) for v in tokens[2:14 if t == 1 else _COUNTS[t]]]
            color = int(tokens[1], 0) if tokens[1].lower().startswith("0x") else int(tokens[1])
        except ValueError:
            raise InputError(f"LDraw line {number}: a field is not a number: {raw.strip()!r}")
        if not np.all(np.isfinite(values)):
            raise InputError(f"LDraw line {number}: a coordinate is not finite")
        current.lines += 1
        if t == 1:
            rot = np.array(values[3:12]).reshape(3, 3)
            if abs(np.linalg.det(rot)) < 1e-9:
                raise InputError(f"LDraw line {number}: the rotation matrix is singular")
            name = raw.split(None, 14)[14].strip()
            current.steps[-1].append(Reference(color, np.array(values[:3]), rot, name, step_hide))
            step_hide = None
        elif t == 3:
            tris[current.name].append(values)
        elif t == 4:
            current.quads += 1
    for name, f in files.items():
        if len(f.steps) > 1 and not f.steps[-1]:
            f.steps.pop()
        if tris[name]:
            f.triangles = np.array(tris[name], dtype=float).reshape(-1, 3, 3)
    if not files:
        raise InputError("the LDraw text has no content")
    return LDrawDocument(files)


def placed_bricks(doc: LDrawDocument, shape) -> list[dict]:
    """The catalog bricks the main model references, back in grid cells.

    One dict per ``<number>.dat`` reference: ``part``, ``cell`` (i, j, k),
    ``size`` (x, y, z) in cells, ``color``, ``step`` (1-based) and ``step_hide`` (LeoCAD's
    first step without it, None: never).  Raises
    InputError for a part that is not in the catalog, a rotation that is not
    one of the two a layout uses, or a position off the grid.
    """
    shift = centring_shift(shape)
    out = []
    for n, refs in enumerate(doc.main.steps, start=1):
        for r in refs:
            number = r.name.lower().removesuffix(".dat")
            if not r.name.lower().endswith(".dat"):
                continue
            part = BY_NUMBER.get(number)
            if part is None:
                raise InputError(f"LDraw reference to {r.name}, which is not a catalog part")
            w, d = part.footprint
            if np.allclose(r.rotation, np.eye(3)):
                sx, sy = d, w
            elif np.allclose(r.rotation, TURNED):
                sx, sy = w, d
            else:
                raise InputError(f"LDraw reference to {r.name} has an unexpected rotation")
            sz = part.layers
            i = (r.position[0] + shift[0] - STUD_LDU * sx / 2) / STUD_LDU
            j = (r.position[2] + shift[1] - STUD_LDU * sy / 2) / STUD_LDU
            k = -r.position[1] / PLATE_LDU - sz
            cell = np.array([i, j, k])
            if not np.allclose(cell, np.round(cell), atol=1e-6):
                raise InputError(f"LDraw reference to {r.name} is not on the stud grid")
            out.append({"part": part.number, "cell": tuple(int(v) for v in np.round(cell)),
                        "size": (sx, sy, sz), "color": r.color, "step": n, "step_hide": r.step_hide})
    return out
