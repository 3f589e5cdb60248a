"""Validation benchmark of printed parts (paper, "VALIDATION"): `make bench`.

For each model with precision features, the high-res regions a designer
would choose are written down below as boxes in model mm (as loaded: the
file's coordinates), each with a comment saying which feature it covers and
where that feature was found (cross-sections of the model: round holes and
bosses, their diameter and extent; CATALOG.md of the models lists the same
"slice probe" holes).  For each model the table gives the whole model's
print time, the printed parts' time (one plate), the LEGO bricks, the
printed parts, the assembly estimate and the speed-ups as the paper
defines them (:func:`core.report.speedups`): over the fabrication time
(the LEGO is built while the parts print, then the parts are pressed on:
the paper's walkthrough), over the print time alone (the paper's
Validation, 2.44x on average there), and, for comparison, over printing and
then building one after the other.

A second table measures every printed part against the model, from the
written files (``layout.json``, ``parts/<id>.stl``) and the model file, not
from the report: the share of the model inside the part's cells that the
part keeps, the model volume lost inside the socket holes and the 0.1 mm
play (the only places where anything may be taken away), what is lost
elsewhere (the engraved id), the studs and sockets engaged, the slicer time
with the supports its pose needs, and whether the STL is one watertight
body.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import manifold3d as m3  # noqa: E402
import trimesh  # noqa: E402

from core import pipeline  # noqa: E402
from core.io import meshes as mesh_io  # noqa: E402
from core.parts.interfaces import Fit  # noqa: E402

MODELS = ROOT.parent / "shared" / "models"
OUT = ROOT / "bench" / "out"

#: model file -> list of (box "X0,Y0,Z0,X1,Y1,Z1" in model mm, the feature it keeps exact).
REGIONS = {
    # Tube-shaped shell along y (x -88.5..88.5, y -35..57.7, z -42..42).  Four
    # corner seats at x = +-65, z = +-30, y 26.25..30.25, each a 4 mm gusset
    # plate with an M3 pilot hole (round hole d 2.8 along y): they carry the
    # lens (eyes) panel.  One box per side, each holding its two seats (the
    # air between them marks nothing).
    MODELS / "relativty_hmd_body.stl": [
        ("-72,24.5,-37,-58,32,37", "left lens-panel screw seats (x -65, z +-30, M3 d2.8)"),
        ("58,24.5,-37,72,32,37", "right lens-panel screw seats (x 65, z +-30, M3 d2.8)"),
    ],
    # Lens plate at y ~ 2..14 with two stepped lens bores (d 37.6 / 40.1 / 42.6,
    # centres x 33 and 108, z 38) and the bayonet slots around them (y ~ 2).
    MODELS / "vr_phone_headset.stl": [
        ("9,-1,14,57,15,62", "left lens bore with its bayonet slots (centre x 33, z 38)"),
        ("84,-1,13,132,15,61", "right lens bore with its bayonet slots (centre x 108, z 37)"),
    ],
    # Chassis floor z 0..4 with walls; six full-height screw seats (bosses with
    # a d 3.4 hole through z 4.4..27.5 and a d 11.5 counterbore at the top) join
    # the bottom to the top body.  One box per seat.
    MODELS / "openbot_body_bottom.step": [
        ("-95,-42,0,-81,-28,29.5", "screw seat, rear left (x -88, y -35)"),
        ("-95,44,0,-81,58,29.5", "screw seat, rear right (x -88, y 51)"),
        ("7,-62,0,21,-48,29.5", "screw seat, middle left (x 14, y -55)"),
        ("7,64,0,21,78,29.5", "screw seat, middle right (x 14, y 71)"),
        ("109,-42,0,123,-28,29.5", "screw seat, front left (x 116, y -35)"),
        ("109,44,0,123,58,29.5", "screw seat, front right (x 116, y 51)"),
    ],
    # Block x 0..~30 with the mounting screws; from x ~ 30 to 92 a C-shaped rail
    # channel (inside y 3..17, z 3..19) open at y 17..20 between lips at z < 6 and
    # z > 16.  In the channel at x ~ 36 a waisted boss (round pin d 4.9..7.5
    # along y, centre z 11) is the screw boss of the sliding phone holder.
    MODELS / "openbot_phone_mount.stl": [
        ("30,14,0,92,20.5,22", "rail: the channel's lips and their outer wall (y 14..20)"),
        ("30,0,4,44,14,18", "screw boss in the channel (x ~ 36, z 11)"),
    ],
    # Tray 10 mm thick (z -5..5), its round end of radius 40 centred at x 0, y 0;
    # the bottle seat is the conical pocket there (d ~ 50 at z -2, 56 at z 0,
    # 62 at z 4) over a 3 mm floor.  The box holds the pocket's wall ring
    # above the grid's first layer (z > -1.8); the flat floor stays LEGO.
    MODELS / "soap_dispenser_holder.stl": [
        ("-41,-41,-1.7,36,36,5", "bottle seat: the pocket's wall ring above the floor"),
    ],
    # examples/hmd.py: lens plate y 32..35 with two ring bosses (d 43, y 26..32)
    # round the lens bores (d 37) at x = +-31.5, z 48.
    ROOT / "examples" / "build" / "hmd.step": [
        ("-54,25,25.5,-9,36,70.5", "left lens mount (ring boss and seat bore, x -31.5, z 48)"),
        ("9,25,25.5,54,36,70.5", "right lens mount (ring boss and seat bore, x 31.5, z 48)"),
    ],
}


def _manifold(mesh: trimesh.Trimesh) -> m3.Manifold:
    return m3.Manifold(m3.Mesh64(vert_properties=np.asarray(mesh.vertices, np.float64),
                                 tri_verts=np.asarray(mesh.faces, np.uint64)))


def _cube(lo, hi) -> m3.Manifold:
    return m3.Manifold.cube(list(np.subtract(hi, lo))).translate(list(lo))


def part_rows(path: Path, out: Path, doc: dict) -> list[tuple]:
    """Per printed part: kept %, lost in sockets+play, lost elsewhere (mm³), engaged, print, solid."""
    import json
    layout = json.loads((out / "layout.json").read_text())
    origin, cell = np.array(layout["origin_mm"]), np.array(layout["cell_mm"])
    shape = tuple(layout["shape"])
    owner = np.full(shape, "", dtype=object)
    for b in layout["bricks"]:
        (i, j, k), (sx, sy, sz) = b["cell"], b["size"]
        owner[i:i + sx, j:j + sy, k:k + sz] = b["printed_part"] or "lego"
    model = _manifold(mesh_io.load_model(path).mesh)
    fit, rows = Fit(), []
    for p in doc["printed_parts"]:
        mine = owner == p["id"]
        cells = m3.Manifold.batch_boolean([_cube(origin + np.array(c) * cell, origin + (np.array(c) + 1) * cell)
                                           for c in np.argwhere(mine)], m3.OpType.Add)
        allowed = []
        for i, j, k in np.argwhere(mine):
            centre = origin + (np.array([i, j, k]) + 0.5) * cell
            if k > 0 and owner[i, j, k - 1] not in ("", p["id"]):
                z0 = origin[2] + k * cell[2]
                allowed.append(_cube([*(centre[:2] - fit.socket_width / 2), z0],
                                     [*(centre[:2] + fit.socket_width / 2), z0 + fit.socket_depth]))
            for axis in (0, 1):
                for sign in (-1, 1):
                    n = np.array([i, j, k])
                    n[axis] += sign
                    if 0 <= n[axis] < shape[axis] and owner[tuple(n)] not in ("", p["id"]):
                        lo = origin + np.array([i, j, k]) * cell
                        hi = lo + cell
                        if sign > 0:
                            lo[axis] = hi[axis] - fit.play
                        else:
                            hi[axis] = lo[axis] + fit.play
                        allowed.append(_cube(lo, hi))
        part = trimesh.load(out / "parts" / f"{p['id']}.stl")
        solid = _manifold(part)
        inside = model ^ cells
        lost = inside - solid
        free = m3.Manifold.batch_boolean(allowed, m3.OpType.Add) if allowed else m3.Manifold()
        rows.append((path.name, p["id"], p["cells"], inside.volume(),
                     100.0 * (inside ^ solid).volume() / max(inside.volume(), 1e-9),
                     (lost ^ free).volume(), (lost - free).volume(),
                     p["engaged"]["studs"], p["engaged"]["sockets"],
                     (p["print_pose"] or {}).get("name", "?"), (p["print_s"] or 0.0) / 60,
                     part.is_watertight and part.body_count == 1))
    return rows


def main() -> int:
    """Run every model, print the table and the mean speed-up; 0 on success."""
    if not MODELS.is_dir():
        print(f"skipped: {MODELS} not found")
        return 0
    rows, gains, parts = [], [], []
    for path, regions in REGIONS.items():
        if not path.exists():
            print(f"skipped {path.name}: not found (run `make demo` for hmd.step)")
            continue
        start = time.perf_counter()
        doc = pipeline.fabricate(path, OUT / path.stem, high_res=[box for box, _ in regions],
                                 picture=False)
        pt = doc["print_time_s"]
        if pt is None:
            print(f"{path.name}: the boxes touch no brick, nothing printed")
            continue
        st = doc["stability"]
        studs = sum(p["engaged"]["studs"] + p["engaged"]["sockets"] for p in doc["printed_parts"])
        sp = doc["speedups"]
        rows.append((path.name, pt["full_model"] / 60, pt["printed_parts"] / 60,
                     doc["bricks"]["lego"], len(doc["printed_parts"]), doc["assembly_s"] / 60,
                     doc["fabrication_s"] / 60, sp["fabrication"], sp["printing"], sp["sequential"],
                     f"{st['components']}/{st['regions']}",
                     str(studs),
                     time.perf_counter() - start, pt["method"]))
        gains.append((sp["fabrication"], sp["printing"], sp["sequential"]))
        parts += part_rows(path, OUT / path.stem, doc)
    print("| model | full min | parts min | LEGO bricks | parts | assembly min | fabrication min "
          "| speed-up | printing only | build after print | components/regions | studs+sockets engaged "
          "| run s | print time by |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    for r in rows:
        print(f"| {r[0]} | {r[1]:.1f} | {r[2]:.1f} | {r[3]} | {r[4]} | {r[5]:.1f} | {r[6]:.1f} "
              f"| {r[7]:.2f} | {r[8]:.2f} | {r[9]:.2f} | {r[10]} | {r[11]} | {r[12]:.1f} | {r[13]} |")
    print()
    print("| model | part | cells | model in cells mm³ | kept % | lost in sockets+play mm³ "
          "| lost elsewhere mm³ | studs | sockets | pose | print min (supports as needed) "
          "| one watertight solid |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|")
    for r in parts:
        print(f"| {r[0]} | {r[1]} | {r[2]} | {r[3]:.0f} | {r[4]:.2f} | {r[5]:.1f} | {r[6]:.1f} "
              f"| {r[7]} | {r[8]} | {r[9]} | {r[10]:.1f} | {r[11]} |")
    if gains:
        mean = np.mean(gains, axis=0)
        print(f"mean speed-up {mean[0]:.2f}x (printing only {mean[1]:.2f}x, paper 2.44x; "
              f"building after printing {mean[2]:.2f}x) over {len(gains)} models")
    return 0


if __name__ == "__main__":
    sys.exit(main())
