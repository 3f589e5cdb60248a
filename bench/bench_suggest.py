"""Suggesting high-res regions (core/suggest.py): seconds per model, `make bench`.

One row per shared model: the triangles, where the features came from (the
B-rep's faces or the mesh), the regions suggested and dropped, the share of the
part's volume and of its cells they mark, and the seconds :func:`core.suggest.suggest` takes
after the model is loaded (best of 3).  The 100k-triangle row is the OpenBot
body's STEP tessellated at 0.01 mm and read as a mesh only (its B-rep left
out); its target is 5 s.  A row over its target ends the script with status 1.
"""

from __future__ import annotations

import dataclasses
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from core import suggest  # noqa: E402
from core.io import meshes as mesh_io  # noqa: E402

MODELS = ROOT.parent / "shared" / "models"
#: (row name, file, load tolerance mm, read as a mesh only, target seconds or None).
ROWS = (
    ("OpenBot body, 100k-triangle mesh", "openbot_body_bottom.step", 0.01, True, 5.0),
    ("OpenBot body, B-rep", "openbot_body_bottom.step", 0.05, False, None),
    ("FreeCAD drilling plate, B-rep", "freecad_drilling_plate.FCStd", 0.05, False, None),
    ("Connecting rod, B-rep", "asm4_connecting_rod.FCStd", 0.05, False, None),
    ("OpenBot motor bracket, mesh", "openbot_motor_bracket.stl", 0.05, True, None),
    ("Relativty lens mount, mesh", "relativty_lens_mount.stl", 0.05, True, None),
)


def main() -> int:
    """Print the table; 1 when a row is over its target."""
    if not MODELS.is_dir():
        print(f"skipped: {MODELS} not found")
        return 0
    print("| model | triangles | from | regions | dropped | share of volume | of cells | suggest s "
          "| target s |")
    print("|---|---|---|---|---|---|---|---|---|")
    over = False
    for name, file, tolerance, mesh_only, target in ROWS:
        path = MODELS / file
        if not path.is_file():
            continue
        model = mesh_io.load_model(path, tolerance_mm=tolerance)
        if mesh_only:
            model = dataclasses.replace(model, brep=None)
        times = []
        for _ in range(3):
            start = time.perf_counter()
            found = suggest.suggest(model)
            times.append(time.perf_counter() - start)
        seconds = min(times)
        over |= target is not None and seconds > target
        print(f"| {name} | {len(model.mesh.faces):,} | {found.source} | {len(found.regions)} | "
              f"{len(found.dropped)} | {found.share:.1%} | {found.cells_share:.1%} | {seconds:.2f} | "
              f"{'-' if target is None else f'{target:g}'} |")
    return 1 if over else 0


if __name__ == "__main__":
    sys.exit(main())
