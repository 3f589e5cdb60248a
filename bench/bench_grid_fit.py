"""Benchmark of the grid fit (core/grid_fit.py): `make bench`.

For the high-res regions of bench/bench_printed.py, the shift the fit
chooses, the sampled model volume in the marked cells and the printed
parts' exact volume with the centred and with the fitted grid, and the
seconds the fit takes.  Nothing is sliced.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "bench"))

from bench_printed import MODELS, REGIONS  # noqa: E402
from core import pipeline  # noqa: E402


def main() -> int:
    """Print the table; 0 on success."""
    if not MODELS.is_dir():
        print(f"skipped: {MODELS} not found")
        return 0
    print("| model | shift x,y mm | marked model mm³ centred | fitted | printed mm³ centred "
          "| fitted | printed cells centred | fitted | fit s |")
    print("|---|---|---|---|---|---|---|---|---|")
    for path, regions in REGIONS.items():
        if not path.exists():
            continue
        boxes = [box for box, _ in regions]
        fitted = pipeline.run(path, high_res=boxes, slice_parts=False)
        centred = pipeline.run(path, high_res=boxes, slice_parts=False, fit_grid=False)
        start = time.perf_counter()
        fit = pipeline.grid_fit.fit(fitted.model.mesh, boxes, closed=fitted.model.watertight)
        seconds = time.perf_counter() - start
        volume = [sum(p.volume_mm3 for p in f.printed) for f in (centred, fitted)]
        cells = [sum(p.cells for p in f.printed) for f in (centred, fitted)]
        print(f"| {path.name} | {fit.shift_mm[0]:g},{fit.shift_mm[1]:g} | {fit.centred_mm3:.0f} "
              f"| {fit.fitted_mm3:.0f} | {volume[0]:.0f} | {volume[1]:.0f} | {cells[0]} | {cells[1]} "
              f"| {seconds:.2f} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
