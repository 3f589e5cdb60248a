"""Benchmark of the assembly outputs (issue: instructions for 3,000 bricks in under 5 s).

Times :func:`core.instructions.page.write_assembly` (build order, instructions.html,
assembly.mpd, bom.csv, bricklink.xml) on layouts made by
:func:`core.layout.greedy.lay_out` from box-shaped grids (hollow boxes with walls
and floor 3 studs / plates thick; the largest has about 3,300 bricks) and on
the bundled example with its two printed lens mounts, and on a few shared
models (``../shared/models``, when present).  Prints a markdown
table: bricks, steps, seconds per stage and in total (best of three runs),
and file sizes.  Layout time is not part of the measurement.
"""

from __future__ import annotations

import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from core import pipeline  # noqa: E402
from core.instructions import page as instructions  # noqa: E402
from core.layout import greedy as layout_stage  # noqa: E402
from core.model import CELL_MM, Grid  # noqa: E402

HMD = ROOT / "examples" / "build" / "hmd.step"
MODELS = ROOT.parent / "shared" / "models"
#: Shared models laid out as a whole (no printed parts), when the folder is there.
SHARED = ("relativty_hmd_body.stl", "openbot_body_bottom.stl", "vr_phone_headset.stl")
HMD_HIGH_RES = ["-54,25,25.5,-9,36,70.5", "9,25,25.5,54,36,70.5"]
#: (footprint studs, height in plates) of the hollow boxes.
BOXES = ((40, 30), (80, 48), (116, 62))
RUNS = 3


def hollow_box(n: int, h: int, wall: int = 3) -> Grid:
    """An n x n x h cell grid: floor and walls ``wall`` cells thick, open on top."""
    filled = np.ones((n, n, h), dtype=bool)
    filled[wall:-wall, wall:-wall, wall:] = False
    return Grid(np.zeros(3), np.array(CELL_MM), filled)


def measure(name: str, layout, printed) -> str:
    """One table row: best of RUNS runs of write_assembly on ``layout``."""
    best, result, sizes = None, None, {}
    for _ in range(RUNS):
        with tempfile.TemporaryDirectory() as tmp:
            start = time.perf_counter()
            result = instructions.write_assembly(layout, printed, tmp, title=name)
            total = time.perf_counter() - start
            sizes = {k: (Path(tmp) / f).stat().st_size for k, f in result["files"].items()}
        if best is None or total < best[0]:
            best = (total, result["timings_s"])
    total, t = best
    return (f"| {name} | {len(layout.bricks)} | {len(printed)} | {result['steps']} | "
            f"{t['order']:.3f} | {t['html']:.3f} | {t['ldraw']:.3f} | {t['bom']:.3f} | "
            f"**{total:.2f}** | {sizes['instructions'] / 1024:.0f} | {sizes['ldraw'] / 1024:.0f} | "
            f"{result['split_bricks']} |")


def main() -> int:
    print("| model | bricks | printed parts | steps | order s | html s | ldraw s | bom s | total s "
          "| instructions.html kB | assembly.mpd kB | bricks drawn as columns |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|")
    for n, h in BOXES:
        layout = layout_stage.lay_out(hollow_box(n, h), seed=0)
        print(measure(f"hollow box {n}x{n}x{h} cells", layout, []), flush=True)
    if HMD.is_file():
        fab = pipeline.run(HMD, high_res=HMD_HIGH_RES, slice_parts=False)
        print(measure("examples/build/hmd.step + 2 lens mounts", fab.layout, fab.printed), flush=True)
    else:
        print(f"(skipped the example: {HMD} not built; run `make demo` or examples/hmd.py)")
    for name in SHARED:
        if (MODELS / name).is_file():
            fab = pipeline.run(MODELS / name)
            print(measure(name, fab.layout, fab.printed), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
