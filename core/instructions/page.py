"""Assembly instructions: one self-contained ``instructions.html`` a person builds from.

The page holds a single isometric SVG picture of the whole model in which every brick is
drawn once, as the three visible faces of its box (top, -x and -y side; view from the front
left, above, as :mod:`core.instructions.render`), and a little script shows one step at a time by
switching each brick's class: bricks of earlier steps grey, the step's bricks blue (dropping
in when played), later bricks hidden.  Printed parts are their meshes shaded in orange
(:mod:`core.instructions.picture`) with their ID on top; the one being inserted is bright, its outline
drawn over everything (so it shows where it goes even behind other bricks), those in place
pale.  Studs are an SVG pattern per layer on the top faces (an affine pattern transform maps
the stud lattice of the plane z = top onto the picture), which keeps big models' pages small.

Bricks are painted back to front (:mod:`core.instructions.drawing_order`).

The page needs no network: CSS, script, pictures and data are inline.  Keys:
right/down/PageDown/Enter = next step, left/up/PageUp = previous, Home/End, space =
play/pause; a swipe left or right on a touch screen; a slider and buttons;
``instructions.html#17`` opens at step 17.  A panel shows the step's parts (picture, count,
design number, name, colour), the layer being built and the time estimate.

:func:`write_assembly` is the pipeline's entry point: it orders the steps
(:mod:`core.instructions.build_order`), sets ``brick.step`` and writes ``instructions.html``,
``assembly.mpd`` (:mod:`core.instructions.ldraw`), ``bom.csv`` and ``bricklink.xml`` (:mod:`core.instructions.bom`).
"""

from __future__ import annotations

import html
import json
import math
import os
import time
from pathlib import Path

import numpy as np

from core.catalog import BY_NUMBER
from core.instructions import bom, build_order, ldraw, picture
from core.instructions.drawing_order import brick_boxes, drawing_pieces
from core.instructions.picture import SQ2, SQ6, fmt, screen
from core.model import Layout

#: Stud radius and height (mm) as drawn.
STUD_R_MM = 2.4
STUD_H_MM = 1.7
#: Face colours per state: (top, -x side, -y side, stud side, stud top).
LEGO_DONE = ("#c9cdd1", "#8d9398", "#a9aeb3", "#979da2", "#dde0e3")
LEGO_NOW = ("#5c9be6", "#245aa8", "#3673c7", "#2f66b5", "#8bbcf2")
PRINTED = ("#fe9a3c", "#b85f0a", "#dc7a18")
#: A printed part already in place: paler, as built LEGO is grey, so the part
#: being inserted (PRINTED) stands out.
PRINTED_DONE = ("#f4d3b2", "#b99479", "#d9b495")
#: Outline of the printed part being inserted, drawn over everything.
INSERT_OUTLINE = "#1d4e9e"
#: Seconds between steps in play mode.
PLAY_MS = 1400

FILES = {"instructions": "instructions.html", "ldraw": "assembly.mpd",
         "bom": "bom.csv", "bricklink": "bricklink.xml"}


def _face_paths(lo, hi) -> tuple[str, str, str]:
    """SVG path data of the top, -x and -y faces of the box ``lo``..``hi`` (mm)."""
    ex = screen(np.array([1.0, 0, 0]))
    ey = screen(np.array([0, 1.0, 0]))
    ez = screen(np.array([0, 0, 1.0]))
    L = np.asarray(hi, float) - np.asarray(lo, float)
    top0 = screen(np.array([lo[0], lo[1], hi[2]]))
    base = screen(np.asarray(lo, float))

    def pair(p) -> str:
        y = fmt(p[1])
        return fmt(p[0]) + ("" if y.startswith("-") else " ") + y

    def path(start, u, v) -> str:
        return f"M{pair(start)}l{pair(u)}l{pair(v)}l{pair(-u)}z"

    return (path(top0, ex * L[0], ey * L[1]),
            path(base, ey * L[1], ez * L[2]),
            path(base, ex * L[0], ez * L[2]))


def _all_face_paths(lo: np.ndarray, hi: np.ndarray) -> list[tuple[str, str, str]]:
    """:func:`_face_paths` of many boxes at once (``lo``, ``hi``: (n, 3) mm), the same text."""
    lo, hi = np.asarray(lo, float).reshape(-1, 3), np.asarray(hi, float).reshape(-1, 3)
    ex, ey, ez = screen(np.eye(3))
    size = hi - lo
    top0 = screen(np.column_stack([lo[:, 0], lo[:, 1], hi[:, 2]])).tolist()
    base = screen(lo).tolist()
    u_x, u_y, u_z = (np.outer(size[:, d], e) for d, e in enumerate((ex, ey, ez)))
    u_x, u_y, u_z, m_x, m_y = (a.tolist() for a in (u_x, u_y, u_z, -u_x, -u_y))
    cache: dict[float, str] = {}

    def one(v: float) -> str:
        out = cache.get(v)
        if out is None:
            out = cache[v] = fmt(v)
        return out

    def pair(p) -> str:
        y = one(p[1])
        return one(p[0]) + ("" if y.startswith("-") else " ") + y

    def path(start, u, v, mu) -> str:
        return f"M{pair(start)}l{pair(u)}l{pair(v)}l{pair(mu)}z"

    return [(path(top0[n], u_x[n], u_y[n], m_x[n]), path(base[n], u_y[n], u_z[n], m_y[n]),
             path(base[n], u_x[n], u_z[n], m_x[n])) for n in range(len(lo))]


def _column_paths(lo, hi, brick_lo, brick_hi) -> tuple[list[tuple[str, str]], str]:
    """Faces (class, path data) and outline path data of a 1 x 1 column of a split brick.

    The column shows its top, and its -x / -y side where that side is on the
    brick's boundary; the outline keeps only the brick's own edges, so the
    columns of a brick look like the brick.
    """
    top, left, front = _face_paths(lo, hi)
    faces = [("t", top)]
    x0, y0, z0 = (float(v) for v in lo)
    x1, y1, z1 = (float(v) for v in hi)
    on = {"x0": np.isclose(x0, brick_lo[0]), "x1": np.isclose(x1, brick_hi[0]),
          "y0": np.isclose(y0, brick_lo[1]), "y1": np.isclose(y1, brick_hi[1])}
    segments = []
    if on["x0"]:
        faces.insert(0, ("l", left))
        segments += [((x0, y0, z1), (x0, y1, z1)), ((x0, y0, z0), (x0, y1, z0))]
        if on["y1"]:
            segments.append(((x0, y1, z0), (x0, y1, z1)))
    if on["y0"]:
        faces.insert(0, ("f", front))
        segments += [((x0, y0, z1), (x1, y0, z1)), ((x0, y0, z0), (x1, y0, z0))]
        if on["x1"]:
            segments.append(((x1, y0, z0), (x1, y0, z1)))
    if on["x0"] and on["y0"]:
        segments.append(((x0, y0, z0), (x0, y0, z1)))
    if on["x1"]:
        segments.append(((x1, y0, z1), (x1, y1, z1)))
    if on["y1"]:
        segments.append(((x0, y1, z1), (x1, y1, z1)))
    pts = screen(np.array(segments, dtype=float).reshape(-1, 2, 3)) if segments else np.zeros((0, 2, 2))
    edges = "".join(f"M{fmt(a[0])} {fmt(a[1])}L{fmt(b[0])} {fmt(b[1])}" for a, b in pts)
    return faces, edges


def _stud_pattern(pid: str, z_mm: float, cell, colors) -> str:
    """An SVG pattern of studs on the plane z = ``z_mm`` in picture coordinates."""
    cx, cy = float(cell[0]), float(cell[1])
    a, b, c, d = 1 / SQ2, -1 / SQ6, -1 / SQ2, -1 / SQ6
    f = -2.0 * z_mm / SQ6
    r, h = STUD_R_MM, STUD_H_MM
    mx, my = cx / 2, cy / 2
    n = np.array([1.0, -1.0]) / SQ2 * r
    quad = [(mx + n[0], my + n[1]), (mx + h + n[0], my + h + n[1]),
            (mx + h - n[0], my + h - n[1]), (mx - n[0], my - n[1])]
    pts = " ".join(f"{fmt(x)},{fmt(y)}" for x, y in quad)
    return (f'<pattern id="{pid}" patternUnits="userSpaceOnUse" width="{fmt(cx)}" height="{fmt(cy)}" '
            f'patternTransform="matrix({a:.6f} {b:.6f} {c:.6f} {d:.6f} 0 {f:.4f})">'
            f'<rect width="{fmt(cx)}" height="{fmt(cy)}" fill="{colors[0]}"/>'
            f'<circle cx="{fmt(mx)}" cy="{fmt(my)}" r="{fmt(r)}" fill="{colors[3]}"/>'
            f'<polygon points="{pts}" fill="{colors[3]}"/>'
            f'<circle cx="{fmt(mx + h)}" cy="{fmt(my + h)}" r="{fmt(r)}" fill="{colors[4]}" '
            f'stroke="{colors[1]}" stroke-width="0.25"/></pattern>')


def _icon(number: str, cell) -> str:
    """A ``<symbol>`` picture of catalog part ``number`` (long side along x), studs drawn."""
    part = BY_NUMBER[number]
    w, d = part.footprint
    cell = np.asarray(cell, float)
    hi = np.array([d, w, part.layers]) * cell
    lo = np.zeros(3)
    top, left, front = _face_paths(lo, hi)
    rx, ry = STUD_R_MM, STUD_R_MM / np.sqrt(3.0)
    hs = 2 * STUD_H_MM / SQ6
    studs = []
    for i in range(d):
        for j in range(w):
            cxy = screen(np.array([(i + 0.5) * cell[0], (j + 0.5) * cell[1], hi[2]]))
            studs.append(f'<ellipse cx="{fmt(cxy[0])}" cy="{fmt(cxy[1])}" rx="{fmt(rx)}" ry="{fmt(ry)}" class="ss"/>'
                         f'<rect x="{fmt(cxy[0] - rx)}" y="{fmt(cxy[1] - hs)}" width="{fmt(2 * rx)}" '
                         f'height="{fmt(hs)}" class="ss" stroke="none"/>'
                         f'<ellipse cx="{fmt(cxy[0])}" cy="{fmt(cxy[1] - hs)}" rx="{fmt(rx)}" ry="{fmt(ry)}" class="st"/>')
    corners = screen(np.array([[x, y, z] for x in (0, hi[0]) for y in (0, hi[1])
                               for z in (0, hi[2] + STUD_H_MM)]))
    (x0, y0), (x1, y1) = corners.min(axis=0) - 1, corners.max(axis=0) + 1
    # far studs (larger i + j) first
    studs = [s for _, s in sorted(zip([-(i + j) for i in range(d) for j in range(w)], studs),
                                  key=lambda t: t[0])]
    return (f'<symbol id="i{number}" viewBox="{fmt(x0)} {fmt(y0)} {fmt(x1 - x0)} {fmt(y1 - y0)}">'
            f'<path class="l" d="{left}"/><path class="f" d="{front}"/><path class="t" d="{top}"/>'
            + "".join(studs) + "</symbol>")


def _prop_pictures(layout: Layout, order: build_order.BuildOrder, current: int) -> tuple[str, str]:
    """The props of ``order`` as boxes from the table up to their cell: (faces, drawn
    under the bricks, which hide them where they are in front; dashed edges, drawn over
    the bricks, so that a hidden prop still shows).  One ``<g class="pr">`` per prop in
    each, with ``data-s`` (the step it is stood before) and ``data-e`` (the last step it
    stands, :func:`core.instructions.build_order.prop_last_step`), shown from the one to the other."""
    if not order.props:
        return "", ""
    cell = np.asarray(layout.grid.cell, dtype=float)
    lo = np.array([[p["cell"][0], p["cell"][1], 0] for p in order.props], dtype=float) * cell
    hi = lo + np.array([[cell[0], cell[1], p["plates"] * cell[2]] for p in order.props])
    faces, edges = [], []
    for p, (top, left, front) in zip(order.props, _all_face_paths(lo, hi)):
        end = build_order.prop_last_step(p, len(order.steps))
        shown = "" if p["step"] <= current <= end else ' style="display:none"'
        head = f'<g class="pr" data-s="{p["step"]}" data-e="{end}"{shown}>'
        faces.append(f'{head}<path class="l" d="{left}"/><path class="f" d="{front}"/>'
                     f'<path class="t" d="{top}"/></g>')
        edges.append(f'{head}<path class="e" d="{left} {front} {top}"/></g>')
    return "".join(faces), "".join(edges)


def svg_picture(layout: Layout, order: build_order.BuildOrder, current: int = 1,
                printed_parts=()) -> tuple[str, dict]:
    """The model picture as an ``<svg>`` element, with every brick's group classed for step
    ``current``, and facts about it (``pieces`` drawn, ``split_bricks``, ``view_box``,
    ``meshed_parts``: ids of the printed parts drawn from their meshes).

    Each brick is one ``<g class="b ...">`` with ``data-s`` (its step) and
    ``data-id``, or one such group per column where :func:`drawing_pieces`
    split it.  A brick of a printed part in ``printed_parts`` (objects with
    ``id``, ``bricks`` and ``mesh``) draws the part's mesh inside it
    (:func:`core.instructions.picture.part_faces`), not a box; each such part also has
    its outline (:func:`core.instructions.picture.outline`) in ``<g id="outlines">``,
    drawn over everything, which the page shows while the part is being
    inserted.  Printed bricks of other parts are orange boxes."""
    grid = layout.grid
    cell = np.asarray(grid.cell, dtype=float)
    boxes = brick_boxes(layout)
    pieces, owner, order_idx, split = drawing_pieces(layout)
    step_of = order.step_of()
    meshed = _meshed_parts(layout, printed_parts, pieces, owner)
    corners = np.array([[x, y, z] for x in (0, 1) for y in (0, 1) for z in (0, 1)], dtype=float)
    nx, ny, nz = grid.shape
    extent = np.array([nx, ny, nz]) * cell + [0, 0, STUD_H_MM]
    pts = screen(corners * extent)
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    pad = 0.04 * float(max(hi - lo)) + 4.0
    vb = (lo[0] - pad, lo[1] - pad, hi[0] - lo[0] + 2 * pad, hi[1] - lo[1] + 2 * pad)

    tops = sorted({int(round(b.cell[2] + b.size[2])) for b in layout.bricks if b.kind != "printed"})
    defs = [_stud_pattern(f"d{k}", k * cell[2], cell, LEGO_DONE) for k in tops]
    defs += [_stud_pattern(f"n{k}", k * cell[2], cell, LEGO_NOW) for k in tops]
    base = screen(np.array([[0, 0, 0], [nx * cell[0], 0, 0], [nx * cell[0], ny * cell[1], 0],
                            [0, ny * cell[1], 0]]))
    ground = " ".join(f"{fmt(x)},{fmt(y)}" for x, y in base)
    groups = []
    whole = np.all(pieces == boxes[owner], axis=(1, 2)).tolist()
    faces_of = _all_face_paths(boxes[:, 0], boxes[:, 1])
    for piece in order_idx.tolist():
        n = int(owner[piece])
        b = layout.bricks[n]
        s = step_of.get(b.id, 0)
        state = "done" if s < current else "now" if s == current else "todo"
        printed = b.kind == "printed"
        top_class = "t" if printed else f"t z{int(b.cell[2] + b.size[2])}"
        head = f'<g class="b{" pp" if printed else ""} {state}" data-s="{s}" data-id="{b.id}">'
        if printed and b.printed_part in meshed:
            body = "".join(f'<path class="{c}" d="{d}"/>' for c, d in meshed[b.printed_part][1].get(int(piece), ()))
            groups.append(f'{head}{body}</g>')
        elif whole[piece]:
            top, left, front = faces_of[n]
            groups.append(f'{head}<path class="l" d="{left}"/><path class="f" d="{front}"/>'
                          f'<path class="{top_class}" d="{top}"/></g>')
        else:
            faces, edges = _column_paths(pieces[piece, 0], pieces[piece, 1], boxes[n, 0], boxes[n, 1])
            body = "".join(f'<path class="cf {top_class if c == "t" else c}" d="{d}"/>' for c, d in faces)
            groups.append(f'{head}{body}<path class="e" d="{edges}"/></g>')
    labels = []
    font = max(4.0, 0.035 * float(max(hi - lo)))
    parts: dict[str, list[int]] = {}
    for n, b in enumerate(layout.bricks):
        if b.kind == "printed" and b.printed_part is not None:
            parts.setdefault(b.printed_part, []).append(n)
    for pid, members in parts.items():
        top_z = boxes[members, 1, 2].max()
        highest = [n for n in members if boxes[n, 1, 2] == top_z]
        centre = np.array([(boxes[highest, 0, :2].min(axis=0) + boxes[highest, 1, :2].max(axis=0)) / 2])
        xy = screen(np.array([centre[0, 0], centre[0, 1], top_z]))
        s = step_of.get(layout.bricks[members[0]].id, 0)
        state = "done" if s < current else "now" if s == current else "todo"
        labels.append(f'<text class="lbl {state}" data-s="{s}" x="{fmt(xy[0])}" y="{fmt(xy[1])}" '
                      f'font-size="{fmt(font)}">{html.escape(pid)}</text>')
    outlines = []
    for pid, (members, _, path) in meshed.items():
        s = step_of.get(layout.bricks[members[0]].id, 0)
        state = "done" if s < current else "now" if s == current else "todo"
        outlines.append(f'<path class="ol {state}" data-s="{s}" data-part="{html.escape(pid)}" '
                        f'd="{path}"/>')
    props = _prop_pictures(layout, order, current)
    css = "".join(f"#model .done .t.z{k}{{fill:url(#d{k})}}#model .now .t.z{k}{{fill:url(#n{k})}}"
                  for k in tops)
    svg = (f'<svg id="model" xmlns="http://www.w3.org/2000/svg" viewBox="{" ".join(fmt(v) for v in vb)}" '
           f'preserveAspectRatio="xMidYMid meet" role="img" aria-label="model picture">'
           f'<style>{css}</style><defs>{"".join(defs)}</defs>'
           f'<polygon class="ground" points="{ground}"/>'
           f'<g id="props">{props[0]}</g>'
           f'<g id="bricks">{"".join(groups)}</g><g id="outlines">{"".join(outlines)}</g>'
           f'<g id="propedges">{props[1]}</g><g id="labels">{"".join(labels)}</g></svg>')
    return svg, {"pieces": len(groups), "split_bricks": split, "view_box": vb,
                 "meshed_parts": sorted(meshed)}


def _meshed_parts(layout: Layout, printed_parts, pieces: np.ndarray, owner: np.ndarray) -> dict:
    """Per printed part with a mesh: its brick indices, its faces per drawing piece
    (:func:`core.instructions.picture.part_faces`) and its outline path data."""
    index = {b.id: n for n, b in enumerate(layout.bricks)}
    cell = np.asarray(layout.grid.cell, float)
    out = {}
    for part in printed_parts:
        mesh = getattr(part, "mesh", None)
        members = [index[i] for i in part.bricks if i in index]
        if mesh is None or len(mesh.faces) == 0 or not members:
            continue
        piece_of_cell = np.full(layout.grid.shape, -1, np.int64)
        for piece in np.flatnonzero(np.isin(owner, members)):
            lo = np.rint(pieces[piece, 0] / cell).astype(int)
            hi = np.rint(pieces[piece, 1] / cell).astype(int)
            piece_of_cell[lo[0]:hi[0], lo[1]:hi[1], lo[2]:hi[2]] = piece
        cells = np.argwhere(piece_of_cell >= 0)
        out[part.id] = (members, picture.part_faces(mesh, layout.grid.origin, cell, piece_of_cell, cells),
                        picture.outline(mesh, layout.grid.origin))
    return out


def _step_data(layout: Layout, order: build_order.BuildOrder, printed_parts,
               colouring: dict | None = None) -> list[dict]:
    """JSON-ready step list for the page's script (each part in ``colouring``'s colours)."""
    info = {p.id: p for p in printed_parts}
    out = []
    lego_color = ldraw.color_name(ldraw.LEGO_COLOR)
    warnings = step_warnings(order, layout)
    index = {b.id: b for b in layout.bricks}
    for s in order.steps:
        item = {"n": s.number, "k": s.layer, "a": s.attached, "e": s.early,
                "nb": len(s.bricks), "p": s.printed_part, "c": []}
        if s.number in warnings:
            item["w"] = warnings[s.number]
        for number, count in build_order.callout(layout, s, index):
            part = BY_NUMBER.get(number)
            shades = {lego_color: count}
            if colouring is not None:
                shades = {}
                for bid in s.bricks:
                    if index[bid].part == number and bid in colouring:
                        shade = ldraw.color_name(colouring[bid][0])
                        shades[shade] = shades.get(shade, 0) + 1
            for shade, n in sorted(shades.items(), key=lambda kv: (-kv[1], kv[0])):
                item["c"].append([number, part.name if part else number, n, shade])
        if s.printed_part is not None:
            p = info.get(s.printed_part)
            item["pv"] = None if p is None else round(float(p.volume_mm3) / 1000.0, 1)
            item["pf"] = None if p is None else (p.stl or f"parts/{p.id}.stl")
            item["pe"] = p is not None and bool(p.engraved)
        out.append(item)
    return out


def step_warnings(order: build_order.BuildOrder, layout: Layout) -> dict[int, str]:
    """Step number -> the warning the builder reads at that step: the partial build does
    not stand after it (:func:`core.instructions.build_order.standing`'s ``unstable``), or it stands with
    its hardest joint above :data:`core.instructions.build_order.FRAGILE` of its clutch; or, at the first
    of a run of steps checked by the brick graph only (a NaN utilisation), that the forces
    of the partial builds from there on were not checked.  The props of ``order`` (bricks of
    ``layout``) come first: where to stand one, before its step; that it can go, after the
    step the build stands without it."""
    out = {u["step"]: "Does not stand on its own: " + u["why"] + "." for u in order.unstable}
    props: dict[int, list[str]] = {}
    for p in order.props:
        props.setdefault(p["step"], []).append("Prop: " + build_order.prop_words(layout, p) + ".")
        if p["removed_after"] is not None:
            props.setdefault(p["removed_after"], []).append(
                f"After this step, take away the prop stood before step {p['step']}: the build "
                "now stands without it.")
    before = 0.0
    for n, value in enumerate(order.utilisation, start=1):
        if n not in out and build_order.FRAGILE < value:
            out[n] = (f"Fragile: after this step the hardest-working joint uses {value:.0%} of its "
                      "clutch. Press the bricks fully home and handle the build gently.")
        elif n not in out and math.isnan(value) and not math.isnan(before):
            out[n] = ("Not force-checked from here on: the build has too many bricks for the "
                      "force check of each step, so these steps were only checked to be joined "
                      "to the ground. Support overhanging bricks until what holds them is on.")
        before = value
    for n, words in props.items():
        out[n] = " ".join(words + ([out[n]] if n in out else []))
    return out


def _minutes(seconds: float) -> str:
    m = int(round(seconds / 60.0))
    return f"{m // 60} h {m % 60:02d} min" if m >= 60 else f"{m} min"


def page(layout: Layout, order: build_order.BuildOrder, printed_parts=(), title: str = "",
         assembly_s: float | None = None, colouring: dict | None = None,
         printed_on: str | None = None) -> tuple[str, dict]:
    """The whole ``instructions.html`` text, and facts about its picture; its summary
    ends with "printed on: ``printed_on``" when that names the printer.

    Raises ValueError when ``order`` does not cover every brick of ``layout``.
    """
    step_of = order.step_of()
    missing = [b.id for b in layout.bricks if b.id not in step_of]
    if missing:
        raise ValueError(f"{len(missing)} brick(s) are in no assembly step (e.g. {missing[:5]})")
    svg, facts = svg_picture(layout, order, current=1, printed_parts=printed_parts)
    rows = bom.lines(layout, printed_parts, order.props, colouring)
    used = sorted({r.part for r in rows if r.kind != "printed" and r.part in BY_NUMBER})
    icons = "".join(_icon(n, layout.grid.cell) for n in used)
    bom_rows = "".join(
        f"<tr><td><svg class='ic'><use href='#i{html.escape(r.part)}'/></svg></td>"
        f"<td>{r.count}</td><td>{html.escape(r.part)}</td><td>{html.escape(r.name)}</td>"
        f"<td>{html.escape(r.color)}</td></tr>" if r.kind != "printed" else
        f"<tr><td><span class='pp-sw'></span></td><td>1</td><td>{html.escape(r.part)}</td>"
        f"<td>Printed part ({r.bricks_replaced} bricks' place, {r.volume_mm3 / 1000:.1f} cm³, "
        f"print ≈ {_minutes(r.print_s or 0)})</td><td>{html.escape(r.file)}</td></tr>"
        for r in rows)
    nz = layout.grid.shape[2]
    data = {"steps": _step_data(layout, order, printed_parts, colouring), "layers": int(nz),
            "layer_mm": float(layout.grid.cell[2]), "play_ms": PLAY_MS}
    blob = json.dumps(data, separators=(",", ":")).replace("</", "<\\/")
    lego = sum(1 for b in layout.bricks if b.kind != "printed")
    n_parts = len({b.printed_part for b in layout.bricks if b.kind == "printed"})
    summary = (f"{lego} LEGO bricks, {n_parts} printed part{'s' if n_parts != 1 else ''}, "
               f"{len(order.steps)} steps")
    if assembly_s is not None:
        summary += f", about {_minutes(assembly_s)} to build"
    if printed_on and n_parts:
        summary += f"; printed on: {printed_on}"
    warn = ""
    if order.unattached or order.early_parts:
        bits = []
        if order.unattached:
            bits.append(f"{len(order.unattached)} brick(s) attach to nothing when placed "
                        "(the layout is not connected there): hold them in place")
        if order.early_parts:
            bits.append("printed part(s) " + ", ".join(order.early_parts)
                        + " go in before everything under them is built")
        warn = f'<p class="warn">{html.escape("; ".join(bits))}.</p>'
    title = title or "Fabrickator assembly"
    text = _TEMPLATE.format(title=html.escape(title), summary=html.escape(summary), warn=warn,
                            svg=svg, icons=icons, bom_rows=bom_rows, data=blob,
                            nsteps=len(order.steps), css=_css(), js=_JS)
    return text, facts


def write_instructions(layout: Layout, order: build_order.BuildOrder, path: str | os.PathLike,
                       printed_parts=(), title: str = "", assembly_s: float | None = None,
                       colouring: dict | None = None, printed_on: str | None = None) -> dict:
    """Write ``instructions.html`` at ``path`` (:func:`page`); returns facts about its picture and size."""
    text, facts = page(layout, order, printed_parts, title, assembly_s, colouring, printed_on)
    Path(path).write_text(text, encoding="utf-8")
    facts["bytes"] = len(text.encode("utf-8"))
    return facts


def write_assembly(layout: Layout, printed_parts, folder: str | os.PathLike, title: str = "",
                   seconds_per_brick: float = build_order.SECONDS_PER_BRICK,
                   seconds_per_part: float = build_order.SECONDS_PER_PART,
                   bricks_per_step: int = build_order.BRICKS_PER_STEP,
                   order: build_order.BuildOrder | None = None, colouring: dict | None = None,
                   inventory=None, bought: int = ldraw.LEGO_COLOR, printed_on: str | None = None) -> dict:
    """Write the builder's files of ``layout`` into ``folder``, in the build ``order``
    (planned here when None; ``layout`` is not changed); ``printed_on`` names the printer
    the instructions say the parts are printed on.

    Writes ``instructions.html``, ``assembly.mpd`` (LDraw MPD with ``0 STEP``
    per step and the printed parts embedded), ``bom.csv`` and
    ``bricklink.xml``; with an ``inventory`` (:class:`core.inventory.Inventory`) and its
    ``colouring`` (:func:`core.inventory.colour`) each brick in its colour, the parts list
    with owned and to-buy counts and the wanted list only what is to buy (in ``bought``
    where a prop needs more).  Returns a dict for ``report.json``: ``steps``,
    ``layers``, ``bricks_per_step``, ``assembly_s`` (``seconds_per_brick``
    per LEGO brick + ``seconds_per_part`` per printed part, both echoed),
    ``unattached_bricks`` and ``early_parts`` (see
    :class:`core.instructions.build_order.BuildOrder`), ``split_bricks`` (bricks the
    picture draws as columns, see :func:`drawing_pieces`), ``files`` (role ->
    file name) and ``timings_s``.  Raises
    FileNotFoundError for a folder that does not exist (the caller makes
    it), InputError for seconds per brick or part that are not a number of
    seconds >= 0 (the user's settings, :func:`core.instructions.build_order.assembly_seconds`)
    and ValueError for a bad ``bricks_per_step``.
    """
    folder = Path(folder)
    if not folder.is_dir():
        raise FileNotFoundError(f"cannot write the assembly files: folder {folder} does not exist")
    printed_parts = list(printed_parts or [])
    timings = {}
    t = time.perf_counter()
    seconds = build_order.assembly_seconds(layout, seconds_per_brick, seconds_per_part)
    if order is None:
        order = build_order.plan(layout, bricks_per_step)
    layout = build_order.numbered(layout, order)
    timings["order"] = time.perf_counter() - t
    t = time.perf_counter()
    facts = write_instructions(layout, order, folder / FILES["instructions"], printed_parts,
                               title, seconds, colouring, printed_on)
    timings["html"] = time.perf_counter() - t
    t = time.perf_counter()
    ldraw.write(layout, printed_parts, order.steps, folder / FILES["ldraw"], title=title, props=order.props,
                codes=None if colouring is None else {i: c for i, (c, _) in colouring.items()})
    timings["ldraw"] = time.perf_counter() - t
    t = time.perf_counter()
    bom.write_csv(bom.lines(layout, printed_parts, order.props, colouring), folder / FILES["bom"])
    buying = None if inventory is None else bom.to_buy(layout, colouring, inventory, bought,
                                                        order.props)
    bom.write_wanted_list(layout, folder / FILES["bricklink"], remarks=title, props=order.props,
                          buying=buying)
    timings["bom"] = time.perf_counter() - t
    return {
        "steps": len(order.steps),
        "layers": order.layers,
        "bricks_per_step": bricks_per_step,
        "assembly_s": round(seconds, 1),
        "seconds_per_brick": float(seconds_per_brick),
        "seconds_per_part": float(seconds_per_part),
        "unattached_bricks": list(order.unattached),
        "early_parts": list(order.early_parts),
        "split_bricks": facts["split_bricks"],
        "files": dict(FILES),
        "timings_s": {k: round(v, 4) for k, v in timings.items()},
    }


_CSS_TEMPLATE = """
*{box-sizing:border-box}
html,body{margin:0;height:100%;font-family:system-ui,-apple-system,"Segoe UI",Roboto,sans-serif;
 background:#f4f5f7;color:#1d2329}
body{display:flex;flex-direction:column;touch-action:pan-y}
header{display:flex;align-items:center;gap:1em;padding:.4em .8em;background:#1f3a5f;color:#fff;flex-wrap:wrap}
header h1{font-size:1.1em;margin:0;font-weight:600}
header .sum{opacity:.85;font-size:.9em}
main{flex:1;display:flex;min-height:0}
#stage{flex:1;min-width:0;position:relative;display:flex}
#model{width:100%;height:100%;display:block}
aside{width:19em;max-width:45%;padding:.8em;background:#fff;border-left:1px solid #d9dde2;
 overflow:auto;display:flex;flex-direction:column;gap:.8em}
#stepline{font-size:1.6em;font-weight:700}
#stepline small{font-size:.55em;font-weight:400;color:#5b6670}
#callout{list-style:none;margin:0;padding:0;display:flex;flex-direction:column;gap:.4em}
#callout li{display:flex;align-items:center;gap:.6em;padding:.3em;border:1px solid #e1e5ea;border-radius:6px}
#callout .cnt{font-size:1.3em;font-weight:700;min-width:2.2em;text-align:right}
#callout .ic{width:4.2em;height:3em}
#callout .nm{font-size:.9em;line-height:1.2}
#callout .nm b{display:block}
#callout li.printed{background:#fff3e6;border-color:#fe9a3c}
.ic{width:3em;height:2.2em}
#layer{display:flex;gap:.6em;align-items:stretch}
#lbar{width:1.2em;height:7em;background:#e6e9ed;border-radius:4px;position:relative;overflow:hidden}
#lfill{position:absolute;left:0;right:0;bottom:0;background:#3673c7}
#ltext{font-size:.9em;align-self:center}
footer{display:flex;align-items:center;gap:.6em;padding:.5em .8em;background:#fff;border-top:1px solid #d9dde2}
footer button{font-size:1.2em;min-width:2.6em;padding:.25em .5em;border-radius:6px;border:1px solid #aab2bb;background:#f7f8fa}
#slider{flex:1}
.warn{color:#8a4b00;background:#fff3e0;padding:.4em;border-radius:4px;font-size:.85em;margin:0}
details{font-size:.85em}
details table{border-collapse:collapse;width:100%}
details td{border-bottom:1px solid #eceff2;padding:.15em .3em;vertical-align:middle}
.pp-sw{display:inline-block;width:1.4em;height:1em;background:#fe9a3c;border-radius:2px}
.hint{font-size:.8em;color:#6b7680}
#model .ground{fill:#e3e7eb;stroke:#c4cad1;stroke-width:.4}
#model .b path{stroke:#2b3036;stroke-width:.3;stroke-linejoin:round}
#model .todo{display:none}
#model .done .l{fill:@dl@}#model .done .f{fill:@df@}#model .done .t{fill:@dt@}
#model .now .l{fill:@nl@}#model .now .f{fill:@nf@}#model .now .t{fill:@nt@}
#model .pp path{stroke:#7a3f06;stroke-width:.15}
#model .pp .l{fill:@pl@}#model .pp .f{fill:@pf@}#model .pp .t{fill:@pt@}
#model .pp.now path{stroke:#1d4e9e;stroke-width:.5}
#model .b path.cf{stroke-width:.3}
#model .done path.cf.t{stroke:@dt@}#model .done path.cf.l{stroke:@dl@}#model .done path.cf.f{stroke:@df@}
#model .now path.cf.t{stroke:@nt@}#model .now path.cf.l{stroke:@nl@}#model .now path.cf.f{stroke:@nf@}
#model .pp path.cf.t{stroke:@pt@}#model .pp path.cf.l{stroke:@pl@}#model .pp path.cf.f{stroke:@pf@}
#model .b path.e{fill:none;stroke:#2b3036;stroke-width:.3}
#model .pp path.e{stroke:#7a3f06;stroke-width:.15}#model .pp.now path.e{stroke:#1d4e9e;stroke-width:.5}
#model .pp path.me{fill:none;stroke:#6b3604;stroke-width:.25;stroke-linecap:round}
#model .pp.done path.me{stroke:#9a7a60}
#model .pr path{stroke:#5b1a8c;stroke-width:.5;stroke-linejoin:round;pointer-events:none}
#model .pr path.e{fill:none;stroke-dasharray:1.2 .8}
#model .pr .t{fill:#c79be8}#model .pr .l{fill:#9c5cc9}#model .pr .f{fill:#b37ed9}
#model .ol{display:none;fill:none;stroke:@io@;stroke-width:.8;stroke-linejoin:round;pointer-events:none}
#model .ol.now{display:inline}
#model .lbl{font-weight:700;fill:#5a2a00;stroke:#fff;stroke-width:.8;paint-order:stroke;
 text-anchor:middle;dominant-baseline:middle;font-family:sans-serif}
#model .lbl.now{fill:#0d3a80}
#model .lbl.done{opacity:.7}
#attach:empty{display:none}
#model .drop{animation:drop .45s ease-out}
@keyframes drop{from{transform:translateY(-14px);opacity:0}to{transform:none;opacity:1}}
symbol .t{fill:@dt@}symbol .l{fill:@dl@}symbol .f{fill:@df@}
symbol path,symbol ellipse{stroke:#2b3036;stroke-width:.3}
symbol .ss{fill:@ds@}symbol .st{fill:@dst@}
@media (max-aspect-ratio:1/1){main{flex-direction:column}#stage{min-height:0}
 aside{flex:0 0 auto;width:auto;max-width:none;border-left:0;border-top:1px solid #d9dde2;max-height:42%}}
"""


def _css() -> str:
    """The page's stylesheet with the state colours filled in."""
    colors = {"dt": LEGO_DONE[0], "dl": LEGO_DONE[1], "df": LEGO_DONE[2], "ds": LEGO_DONE[3],
              "dst": LEGO_DONE[4], "nt": LEGO_NOW[0], "nl": LEGO_NOW[1], "nf": LEGO_NOW[2],
              "pt": PRINTED[0], "pl": PRINTED[1], "pf": PRINTED[2]}
    colors["io"] = INSERT_OUTLINE
    text = _CSS_TEMPLATE
    for key, value in colors.items():
        text = text.replace(f"@{key}@", value)
    shades = [(state, picture.shade_colours(*palette))
              for state, palette in (("now", PRINTED), ("done", PRINTED_DONE))]
    return text + "".join(f"#model .pp.{state} path.m{level}{{fill:{c};stroke:{c};stroke-width:.2}}"
                          for state, colours in shades for level, c in enumerate(colours))


_JS = r"""
(function(){
const D = JSON.parse(document.getElementById('data').textContent);
const N = D.steps.length;
const groups = Array.from(document.querySelectorAll('#bricks > g, #outlines > path, #labels > text'));
const stepOf = groups.map(g => +g.getAttribute('data-s'));
const props = Array.from(document.querySelectorAll('#props > g, #propedges > g'));
const state = groups.map(g => g.classList.contains('now') ? 1 : g.classList.contains('done') ? 0 : 2);
const el = id => document.getElementById(id);
let cur = 1, timer = null;
function show(s, animate){
  if (!N){ el('stepno').textContent = '0'; el('callout').textContent = 'No bricks to place.'; return; }
  s = Math.max(1, Math.min(N, s));
  const forward = s === cur + 1;
  cur = s;
  for (let i = 0; i < groups.length; i++){
    const want = stepOf[i] < s ? 0 : stepOf[i] === s ? 1 : 2;
    if (want === state[i]) continue;
    const c = groups[i].classList;
    c.remove('done', 'now', 'todo', 'drop');
    c.add(want === 0 ? 'done' : want === 1 ? 'now' : 'todo');
    if (want === 1 && animate && forward) c.add('drop');
    state[i] = want;
  }
  for (const g of props)
    g.style.display = +g.getAttribute('data-s') <= s && s <= +g.getAttribute('data-e') ? '' : 'none';
  const st = D.steps[s - 1];
  el('stepno').textContent = s;
  el('slider').value = s;
  el('layerno').textContent = st.k + 1;
  el('lfill').style.height = (100 * (st.k + 1) / D.layers) + '%';
  el('lheight').textContent = ((st.k) * D.layer_mm).toFixed(1);
  const ul = el('callout');
  ul.textContent = '';
  if (st.p){
    const li = document.createElement('li');
    li.className = 'printed';
    li.innerHTML = '<span class="pp-sw"></span><span class="nm"><b>Insert printed part ' + st.p +
      '</b>' + (st.pe ? 'find the ID ' + st.p + ' engraved on its side' : 'its ID is not engraved: find it by its shape') +
      (st.pv != null ? ' · ' + st.pv + ' cm³' : '') +
      (st.pf ? ' · ' + st.pf : '') + (st.e ? ' · goes in before all under it is built' : '') + '</span>';
    ul.appendChild(li);
  }
  for (const [num, name, count, color] of st.c){
    const li = document.createElement('li');
    li.innerHTML = '<span class="cnt">' + count + '×</span><svg class="ic"><use href="#i' + num +
      '"/></svg><span class="nm"><b>' + name + '</b>' + num + ' · ' + color + '</span>';
    ul.appendChild(li);
  }
  el('attach').textContent = (st.a ? '' : 'Nothing to attach this to yet: hold it in place. ') +
    (st.w || '');
  document.title = 'Step ' + s + ' / ' + N;
}
function go(d){ show(cur + d, true); }
function play(on){
  if (on === undefined) on = !timer;
  if (timer){ clearInterval(timer); timer = null; }
  if (on){
    if (cur >= N) show(1, false);
    timer = setInterval(() => { if (cur >= N) play(false); else go(1); }, D.play_ms);
  }
  el('play').textContent = timer ? '❚❚' : '▶';
  el('play').setAttribute('aria-pressed', timer ? 'true' : 'false');
}
document.addEventListener('keydown', e => {
  if (e.target && e.target.tagName === 'INPUT' && e.target.type !== 'range') return;
  const k = e.key;
  if (k === 'ArrowRight' || k === 'ArrowDown' || k === 'PageDown' || k === 'Enter'){ go(1); }
  else if (k === 'ArrowLeft' || k === 'ArrowUp' || k === 'PageUp' || k === 'Backspace'){ go(-1); }
  else if (k === 'Home'){ show(1, false); }
  else if (k === 'End'){ show(N, false); }
  else if (k === ' ' || k === 'Spacebar'){ play(); }
  else return;
  e.preventDefault();
});
let tx = null, ty = null;
const stage = el('stage');
stage.addEventListener('touchstart', e => { const t = e.changedTouches[0]; tx = t.clientX; ty = t.clientY; }, {passive:true});
stage.addEventListener('touchend', e => {
  if (tx === null) return;
  const t = e.changedTouches[0], dx = t.clientX - tx, dy = t.clientY - ty;
  tx = ty = null;
  if (Math.abs(dx) > 40 && Math.abs(dx) > 1.5 * Math.abs(dy)) go(dx < 0 ? 1 : -1);
}, {passive:true});
el('slider').addEventListener('input', e => show(+e.target.value, false));
el('next').addEventListener('click', () => go(1));
el('prev').addEventListener('click', () => go(-1));
el('play').addEventListener('click', () => play());
window.fabrickator = {show: s => show(s, false), current: () => cur, steps: N, playing: () => !!timer};
const linked = () => { const m = /^#(?:step=)?(\d+)$/.exec(location.hash); return m ? +m[1] : null; };
window.addEventListener('hashchange', () => { if (linked()) show(linked(), false); });
show(linked() || 1, false);
})();
"""

_TEMPLATE = """<!DOCTYPE html>
<html lang="en">
<head>
<meta charset="utf-8">
<meta name="viewport" content="width=device-width, initial-scale=1">
<title>{title}</title>
<style>{css}</style>
</head>
<body>
<header><h1>{title}</h1><span class="sum">{summary}</span></header>
{warn}
<main>
<div id="stage">{svg}</div>
<aside>
<div id="stepline">Step <span id="stepno">1</span> <small>of {nsteps}</small></div>
<ul id="callout"></ul>
<p id="attach" class="warn" role="status"></p>
<div id="layer"><div id="lbar"><div id="lfill"></div></div>
<div id="ltext">Layer <b id="layerno">1</b><br>at <span id="lheight">0.0</span> mm</div></div>
<details><summary>All parts</summary><table>{bom_rows}</table></details>
<p class="hint">Keys: → / ← step, space play, Home / End. Swipe on a tablet.
Grey: built; blue: this step; orange: printed parts; purple: a prop.</p>
</aside>
</main>
<footer><button id="prev" aria-label="previous step">◀</button>
<button id="play" aria-label="play" aria-pressed="false">▶</button>
<button id="next" aria-label="next step">▶▶</button>
<input id="slider" type="range" min="1" max="{nsteps}" value="1" aria-label="step"></footer>
<svg width="0" height="0" style="position:absolute"><defs>{icons}</defs></svg>
<script id="data" type="application/json">{data}</script>
<script>{js}</script>
</body>
</html>
"""
