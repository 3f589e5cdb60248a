"""Validation benchmark of printed parts (paper, "VALIDATION"): `make bench`.

For each model with precision features, the high-res regions a designer
would choose are written down below as boxes, in fractions of the model's
bounding box (0 = min, 1 = max per axis; turned into model mm at run time),
each with a comment saying what it is meant to keep exact.  For each model
the table gives the whole model's print time, the printed parts' time (one
plate), the bricks, the assembly estimate and the speed-up as the paper
defines it: full print time / (parts print time + assembly).
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from core import mesh_io, pipeline  # noqa: E402

MODELS = ROOT.parent / "shared" / "models"
OUT = ROOT / "bench" / "out"

#: model file -> list of (box in bbox fractions (min xyz, max xyz), what it keeps exact).
REGIONS = {
    MODELS / "relativty_hmd_body.stl": [
        ((0.35, 0.0, 0.0), (0.65, 0.25, 0.25), "screen/lens panel seat, front bottom edge"),
        ((0.85, 0.4, 0.75), (1.0, 0.8, 1.0), "M3 screw seat on the right top corner"),
    ],
    MODELS / "vr_phone_headset.stl": [
        ((0.15, 0.7, 0.35), (0.4, 1.0, 0.65), "left lens bore with its bayonet slots"),
        ((0.6, 0.7, 0.35), (0.85, 1.0, 0.65), "right lens bore with its bayonet slots"),
    ],
    MODELS / "openbot_body_bottom.step": [
        ((0.0, 0.0, 0.0), (0.12, 0.2, 1.0), "front-left motor mount screw bosses"),
        ((0.88, 0.8, 0.0), (1.0, 1.0, 1.0), "rear-right motor mount screw bosses"),
    ],
    MODELS / "openbot_phone_mount.stl": [
        ((0.0, 0.0, 0.5), (1.0, 0.35, 1.0), "sliding rail channel along the top"),
    ],
    MODELS / "soap_dispenser_holder.stl": [
        ((0.3, 0.3, 0.0), (0.7, 0.7, 1.0), "bottle seat ring in the middle"),
    ],
    ROOT / "examples" / "build" / "hmd.step": [
        ((0.1, 0.7, 0.6), (0.35, 1.0, 0.9), "left lens mount"),
        ((0.65, 0.7, 0.6), (0.9, 1.0, 0.9), "right lens mount"),
    ],
}


def boxes_mm(path: Path, fractions) -> list[str]:
    """The fraction boxes of ``path`` as "X0,Y0,Z0,X1,Y1,Z1" strings in model mm."""
    lo, hi = mesh_io.load_model(path).mesh.bounds
    out = []
    for a, b, _ in fractions:
        p0, p1 = lo + np.array(a) * (hi - lo), lo + np.array(b) * (hi - lo)
        out.append(",".join(f"{v:.3f}" for v in (*p0, *p1)))
    return out


def main() -> int:
    """Run every model, print the table and the mean speed-up; 0 on success."""
    if not MODELS.is_dir():
        print(f"skipped: {MODELS} not found")
        return 0
    rows, gains = [], []
    for path, fractions in REGIONS.items():
        if not path.exists():
            print(f"skipped {path.name}: not found (run `make demo` for hmd.step)")
            continue
        start = time.perf_counter()
        doc = pipeline.fabricate(path, OUT / path.stem, high_res=boxes_mm(path, fractions),
                                 picture=False)
        pt = doc["print_time_s"]
        if pt is None:
            print(f"{path.name}: the boxes touch no brick, nothing printed")
            continue
        rows.append((path.name, pt["full_model"] / 60, pt["printed_parts"] / 60,
                     doc["bricks"]["lego"], len(doc["printed_parts"]), doc["assembly_s"] / 60,
                     doc["speedup"], time.perf_counter() - start, pt["method"]))
        gains.append(doc["speedup"])
    print(f"{'model':30s} {'full min':>9s} {'parts min':>9s} {'bricks':>6s} {'parts':>5s} "
          f"{'assembly min':>12s} {'speed-up':>8s} {'run s':>6s}  method")
    for r in rows:
        print(f"{r[0]:30s} {r[1]:9.1f} {r[2]:9.1f} {r[3]:6d} {r[4]:5d} {r[5]:12.1f} "
              f"{r[6]:8.2f} {r[7]:6.1f}  {r[8]}")
    if gains:
        print(f"mean speed-up {np.mean(gains):.2f}x over {len(gains)} models (paper: 2.44x)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
