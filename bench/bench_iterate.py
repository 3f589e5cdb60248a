"""``make bench``: design iteration against laying everything out again.

For each case a previous version is fabricated and snapshotted, then a new
version (moved, or locally edited, or both) is (a) fabricated from scratch
and (b) run as an iteration on the previous output (align, diff, keep the
layout, re-lay out the changed neighbourhood, cut only the printed parts
that may have changed).  Both columns exclude loading the new file (shown
on its own).  Prints a markdown table and writes it to
``bench/out/iterate.md``.  Timings are warm: one small model runs first so
numba's compiled code is loaded.
"""

from __future__ import annotations

import sys
import tempfile
from pathlib import Path

import cadquery as cq
import manifold3d as m3
import numpy as np
import trimesh
from scipy.spatial.transform import Rotation

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from core import align, pipeline, result  # noqa: E402
from core.io import meshes as mesh_io  # noqa: E402
from core.printing import export  # noqa: E402

MODELS = ROOT.parent / "shared" / "models"
OUT = ROOT / "bench" / "out"
#: The six screw seats of the OpenBot chassis (bench_printed.py's regions).
SEATS = ["-95,-42,0,-81,-28,29.5", "-95,44,0,-81,58,29.5", "7,-62,0,21,-48,29.5",
         "7,64,0,21,78,29.5", "109,-42,0,123,-28,29.5", "109,44,0,123,58,29.5"]
HMD_MOUNTS = ["-54,25,25.5,-9,36,70.5", "9,25,25.5,54,36,70.5"]


def motion(seed: int = 7) -> np.ndarray:
    """A rotation by an arbitrary angle about an arbitrary axis plus a translation."""
    rng = np.random.default_rng(seed)
    axis = rng.normal(size=3)
    out = np.eye(4)
    out[:3, :3] = Rotation.from_rotvec(np.radians(37.0) * axis / np.linalg.norm(axis)).as_matrix()
    out[:3, 3] = [25.0, -40.0, 12.0]
    return out


def _manifold(mesh: trimesh.Trimesh) -> m3.Manifold:
    return m3.Manifold(m3.Mesh64(vert_properties=np.ascontiguousarray(mesh.vertices, np.float64),
                                 tri_verts=np.ascontiguousarray(mesh.faces, np.uint64)))


def _mesh(solid: m3.Manifold) -> trimesh.Trimesh:
    out = solid.to_mesh64()
    return trimesh.Trimesh(np.asarray(out.vert_properties)[:, :3], np.asarray(out.tri_verts))


def mesh_cases(work: Path) -> list[tuple[str, Path, Path, Path, list[str]]]:
    """(case, previous file, new file, new file unmoved, high-res boxes) on the OpenBot
    chassis STL."""
    src = MODELS / "openbot_body_bottom.stl"
    mesh = mesh_io.load_model(src).mesh
    boss = trimesh.creation.cylinder(radius=5, height=14, sections=48)
    boss.apply_translation([20, 10, 9])
    cutter = trimesh.creation.box(bounds=[[-30, -20, -1], [-6, 4, 6]])
    out = []
    for name, new in (("moved (37° about an oblique axis)", mesh),
                      ("boss added, moved", _mesh(_manifold(mesh) + _manifold(boss))),
                      ("floor opening cut", _mesh(_manifold(mesh) - _manifold(cutter)))):
        path, still = work / f"stl-{len(out)}.stl", work / f"stl-{len(out)}-unmoved.stl"
        moved = new if name.startswith("floor") else align.transform_mesh(new, motion())
        moved.export(path)
        new.export(still)
        out.append((f"openbot_body_bottom.stl: {name}", src, path, still, []))
    return out


def brep_cases(work: Path) -> list[tuple[str, Path, Path, Path, list[str]]]:
    """(case, previous file, new file, new file unmoved, high-res boxes) with printed
    parts (B-rep)."""
    out = []
    src = MODELS / "openbot_body_bottom.step"
    shape = cq.Shape.cast(mesh_io.load_model(src).brep)
    wider = shape.cut(cq.Solid.makeCylinder(3.0, 40.0, cq.Vector(-88, -35, -5)))
    path, still = work / "seat.step", work / "seat-unmoved.step"
    export.write_step(align.transform_brep(wider.wrapped, motion()), path)
    export.write_step(wider.wrapped, still)
    out.append(("openbot_body_bottom.step, 6 printed seats: one seat bore widened, moved",
                src, path, still, SEATS))
    demo = ROOT / "examples" / "build" / "hmd.step"
    if demo.exists():
        hmd = cq.Shape.cast(mesh_io.load_model(demo).brep)
        bore = cq.Solid.makeCylinder(19.5, 15.0, cq.Vector(31.5, 22.0, 48.0), cq.Vector(0, 1, 0))
        path = work / "hmd-bore.step"
        export.write_step(hmd.cut(bore).wrapped, path)
        out.append(("hmd.step, 2 printed lens mounts: right bore widened 1 mm", demo, path, path,
                    HMD_MOUNTS))
    return out


def run_case(name: str, previous_file: Path, new_file: Path, unmoved: Path, high_res: list[str],
             work: Path) -> dict:
    """One row: fabricating the new version again (unmoved, so that the high-res boxes
    still mark it) against the iteration of the moved new version on the previous one."""
    prev = pipeline.run(previous_file, high_res=high_res, slice_parts=False)
    folder = work / f"prev-{abs(hash(name))}"
    result.snapshot(prev, folder)
    full = pipeline.run(unmoved, high_res=high_res, slice_parts=False)
    full_s = sum(v for k, v in full.timings_s.items() if k != "load")
    it = pipeline.run(new_file, previous=folder, slice_parts=False)
    t = it.timings_s
    iter_s = sum(v for k, v in t.items() if k != "load")
    ch = it.iteration.changes
    diff_s = t["legofy"] + t["high_res"]
    return {
        "case": name, "triangles": it.model.triangles, "load new s": t["load"],
        "full run s": full_s, "iteration s": iter_s,
        "align s": t["align"], "diff s": diff_s, "layout s": t["layout"],
        "printed s": t.get("printed_parts", 0.0),
        "align+diff+layout s": t["align"] + diff_s + t["layout"],
        "rotation °": ch["transform"]["rotation_deg"], "residual mm": ch["transform"]["residual_mm"],
        "cells +/-": f"+{ch['cells_added']}/-{ch['cells_removed']}",
        "bricks kept/off/on": f"{ch['bricks_kept']}/{ch['bricks_removed']}/{ch['bricks_changed']}",
        "bricks (full run)": len(full.layout.bricks),
        "bricks unchanged by full run": _same_bricks(prev, full),
        "parts reprinted": ", ".join(ch["parts_reprinted"]) or "-",
        "parts cut (full run)": len(full.printed),
    }


def _same_bricks(prev, full) -> int:
    """Bricks of a fresh layout that equal a previous brick (part and place, same grid)."""
    if not np.allclose(prev.grid.origin, full.grid.origin, atol=1e-6):
        shift = np.rint((full.grid.origin - prev.grid.origin) / prev.grid.cell).astype(int)
    else:
        shift = np.zeros(3, int)
    before = {(b.part, b.size, b.cell) for b in prev.layout.bricks}
    return sum((b.part, b.size, tuple(int(v) for v in np.array(b.cell) + shift)) in before
               for b in full.layout.bricks)


def table(rows: list[dict], columns: list[str]) -> str:
    def cell(v):
        if isinstance(v, float):
            return f"{v:.3g}" if abs(v) < 1e-2 else f"{v:.3f}"
        return "" if v is None else str(v)

    lines = ["| " + " | ".join(columns) + " |", "|" + "---|" * len(columns)]
    lines += ["| " + " | ".join(cell(r.get(c)) for c in columns) + " |" for r in rows]
    return "\n".join(lines)


def main() -> int:
    if not (MODELS / "openbot_body_bottom.stl").exists():
        print(f"skipped: {MODELS} not found")
        return 0
    pipeline.run(MODELS / "xyz_calibration_cube.stl", slice_parts=False)
    with tempfile.TemporaryDirectory(prefix="fabrickator-bench-iterate-") as tmp:
        work = Path(tmp)
        cases = mesh_cases(work) + brep_cases(work)
        rows = [run_case(*case, work) for case in cases]
    columns = ["case", "triangles", "load new s", "full run s", "iteration s", "align s", "diff s",
               "layout s", "printed s", "align+diff+layout s", "rotation °", "residual mm",
               "cells +/-", "bricks kept/off/on", "bricks (full run)", "bricks unchanged by full run",
               "parts reprinted",
               "parts cut (full run)"]
    text = ("## Design iteration vs. fabricating again (seconds, new file's loading excluded)\n\n"
            + table(rows, columns) + "\n")
    print(text)
    OUT.mkdir(parents=True, exist_ok=True)
    (OUT / "iterate.md").write_text(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
