"""The instructions diff of an iteration as one self-contained HTML page (``changes.html``)."""

from __future__ import annotations

import html
import os
from pathlib import Path

import numpy as np

from core.model import Layout

_PAGE_STYLE = """
body{font-family:sans-serif;margin:1.5em;color:#222;max-width:70em}
h1{font-size:1.4em}h2{font-size:1.15em;margin-top:1.6em}
table{border-collapse:collapse;margin:.4em 0}td,th{border:1px solid #bbb;padding:.2em .5em;text-align:left}
th{background:#eee}.off{color:#b00020}.on{color:#00703c}.print{color:#0050b0}
.layers{display:flex;flex-wrap:wrap;gap:1em}.layer{border:1px solid #ccc;padding:.4em}
.note{color:#555;font-size:.9em}
"""


def changes_page(changes: dict, layout: Layout, path: str | os.PathLike, title: str) -> Path:
    """Write the instructions diff as one self-contained HTML file at ``path``.

    Sections: what changed (alignment, cells); 1. take off: LEGO bricks (by
    previous id, part, layer and stud position in the previous build, top
    down) and printed parts to take out; 2. add: LEGO bricks (bottom up)
    and printed parts to insert, with the bricks they replace; 3. print:
    every printed part, whether it must be printed and why; then a top view
    of every layer that changes (kept bricks grey, taken off red dashed,
    added green, printed blue).  Returns the path written.
    """
    ch = changes
    tr = ch["transform"]
    name = f"{title}: changes since the previous version"
    e = html.escape
    rows = [f"<h1>{e(name)}</h1>",
            f"<p>{e(tr['message'])}. Rotation {tr['rotation_deg']:.3g}°, translation "
            f"{', '.join(f'{v:.3g}' for v in tr['translation_mm'])} mm.</p>",
            f"<p>Cells: <span class='on'>+{ch['cells_added']}</span>, "
            f"<span class='off'>-{ch['cells_removed']}</span>. Bricks: {ch['bricks_kept']} kept, "
            f"<span class='off'>{ch['bricks_removed']} to take off</span>, "
            f"<span class='on'>{ch['bricks_changed']} to add</span>; "
            f"<span class='print'>{len(ch['parts_reprinted'])} part(s) to print</span>.</p>",
            "<p class='note'>Layers count plate heights (3.2 mm) from the base, layer 1 at "
            "the bottom, as in the instructions; positions are "
            "studs from the corner of the previous build (x, y).</p>"]
    lego_off = [b for b in ch["take_off"] if b["kind"] != "printed"]
    lego_on = [b for b in ch["add"] if b["kind"] != "printed"]
    rows.append("<h2 class='off'>1. Take off</h2>")
    rows.append(_brick_table(sorted(lego_off, key=lambda b: (-b["cell_previous"][2], b["id"])),
                             "no LEGO bricks to take off", replaces=False))
    if ch["parts_out"]:
        rows.append(f"<p>Take out printed part(s): <b>{e(', '.join(ch['parts_out']))}</b>.</p>")
    rows.append("<h2 class='on'>2. Add (bottom up)</h2>")
    rows.append(_brick_table(sorted(lego_on, key=lambda b: (b["cell_previous"][2], b["id"])),
                             "no LEGO bricks to add", replaces=True))
    for p in ch["parts_in"]:
        what = []
        if p["replaces_part"]:
            what.append(f"the old print of {p['replaces_part']}" if p["replaces_part"] == p["id"]
                        else f"printed part {p['replaces_part']}")
        if p["replaces_bricks"]:
            what.append("LEGO brick(s) " + ", ".join(map(str, p["replaces_bricks"])))
        rows.append(f"<p>Insert printed part <b>{e(p['id'])}</b>"
                    + (f" in place of {e(' and '.join(what))}" if what else "") + ".</p>")
    rows.append("<h2 class='print'>3. Print</h2>")
    if ch["reprint"]:
        rows.append("<table><tr><th>part</th><th>print</th><th>why</th></tr>")
        for r in ch["reprint"]:
            rows.append(f"<tr><td>{e(r['id'])}</td><td>{'yes' if r['reprint'] else 'no, keep'}</td>"
                        f"<td>{e(r['reason'])}</td></tr>")
        rows.append("</table>")
    else:
        rows.append("<p>no printed parts</p>")
    if ch["parts_removed"]:
        rows.append(f"<p>Printed part(s) no longer used: {e(', '.join(ch['parts_removed']))}.</p>")
    rows.append("<h2>Layers that change</h2><div class='layers'>")
    rows += _layer_views(changes, layout)
    rows.append("</div>")
    text = ("<!DOCTYPE html><html><head><meta charset='utf-8'><title>" + e(name) + "</title><style>"
            + _PAGE_STYLE + "</style></head><body>" + "\n".join(rows) + "</body></html>\n")
    path = Path(path)
    path.write_text(text, encoding="utf-8")
    return path


def _brick_table(entries: list[dict], empty: str, replaces: bool) -> str:
    """An HTML table of instruction-diff LEGO bricks."""
    if not entries:
        return f"<p>{html.escape(empty)}</p>"
    head = "<tr><th>brick</th><th>part</th><th>layer</th><th>at (x, y)</th><th>size</th>"
    head += "<th>replaces</th></tr>" if replaces else "</tr>"
    out = ["<table>", head]
    for b in entries:
        x, y, k = b["cell_previous"]
        row = (f"<tr><td>{b['id']}</td><td>{html.escape(b['part'] + ' ' + b['name'])}</td>"
               f"<td>{k + 1}</td><td>{x}, {y}</td>"
               f"<td>{b['size'][0]} x {b['size'][1]} x {b['size'][2]}</td>")
        if replaces:
            row += f"<td>{', '.join(map(str, b['replaces'])) or '-'}</td>"
        out.append(row + "</tr>")
    out.append("</table>")
    return "\n".join(out)


def _layer_views(changes: dict, layout: Layout, px: int = 14) -> list[str]:
    """One small SVG top view per changed layer, in previous-build coordinates:
    kept bricks grey, taken off red (dashed), added LEGO green, added printed blue."""
    ch = changes
    offset = np.asarray(ch["grid_offset"])
    first_new = ch["first_new_id"]
    boxes = [(np.array(b.cell) + offset, b.size, "#ccc") for b in layout.bricks
             if b.id < first_new]
    boxes += [(b["cell_previous"], b["size"], "#d33") for b in ch["take_off"]]
    boxes += [(b["cell_previous"], b["size"], "#36c" if b["kind"] == "printed" else "#2a2")
              for b in ch["add"]]
    layers = sorted({k for c, s, colour in boxes if colour != "#ccc" for k in range(c[2], c[2] + s[2])})
    if not layers:
        return ["<p>no layer changes</p>"]
    lo = np.min([np.asarray(c[:2]) for c, _, _ in boxes], axis=0)
    hi = np.max([np.asarray(c[:2]) + np.asarray(s[:2]) for c, s, _ in boxes], axis=0)
    w, h = (hi - lo) * px
    out = []
    for k in layers:
        shapes = []
        for c, s, colour in boxes:
            if not c[2] <= k < c[2] + s[2]:
                continue
            x, y = (c[0] - lo[0]) * px, (hi[1] - c[1] - s[1]) * px
            style = "fill-opacity:0.25;stroke-dasharray:3,2" if colour == "#d33" else "fill-opacity:0.85"
            shapes.append(f"<rect x='{x}' y='{y}' width='{s[0] * px}' height='{s[1] * px}' "
                          f"style='fill:{colour};stroke:#333;stroke-width:1;{style}'/>")
        out.append(f"<div class='layer'>layer {k + 1}<br><svg xmlns='http://www.w3.org/2000/svg' "
                   f"width='{w}' height='{h}' viewBox='0 0 {w} {h}'>{''.join(shapes)}</svg></div>")
    return out
