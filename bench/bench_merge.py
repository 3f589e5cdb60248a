"""Merging printed bricks: face removal + sewing vs a Boolean fuse (`make bench`).

The paper found Boolean unions of coplanar faces slow and fragile and
merged by removing the tagged faces between neighbours; this table times
:func:`core.parts.brick_solids.merged_solid` both ways on running-bond walls of
2x4 bricks (2, 8 and 20 bricks, best of 3) and checks that both give the
same volume.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from OCP.BRepGProp import BRepGProp  # noqa: E402
from OCP.GProp import GProp_GProps  # noqa: E402

from core.parts.brick_solids import merged_solid  # noqa: E402


def wall(n: int) -> tuple[list, list]:
    """``n`` bricks of a wall two studs deep: 2x4 bricks, courses staggered by two studs."""
    cells, sizes, k = [], [], 0
    while len(cells) < n:
        start = 2 * (k % 2)
        if k % 2:
            cells.append((0, 0, 3 * k))
            sizes.append((2, 2, 3))
        for i in range(3 if k % 2 else 4):
            cells.append((start + 4 * i, 0, 3 * k))
            sizes.append((4, 2, 3))
        k += 1
    return cells[:n], sizes[:n]


def volume(shape) -> float:
    props = GProp_GProps()
    BRepGProp.VolumeProperties_s(shape, props)
    return props.Mass()


def best(fn, repeat: int = 3) -> tuple[float, object]:
    times, value = [], None
    for _ in range(repeat):
        start = time.perf_counter()
        value = fn()
        times.append(time.perf_counter() - start)
    return min(times), value


def main() -> None:
    print("## Merging printed bricks (brick solids built and merged, best of 3)\n")
    print("| bricks | face removal s | Boolean fuse s | method used | same volume |")
    print("|---|---|---|---|---|")
    for n in (2, 8, 20):
        cells, sizes = wall(n)
        t_remove, removed = best(lambda: merged_solid(cells, sizes, method="remove"))
        t_fuse, fused = best(lambda: merged_solid(cells, sizes, method="fuse"))
        same = abs(volume(removed.shape) - volume(fused.shape)) < 1e-6 * volume(fused.shape)
        print(f"| {n} | {t_remove:.3f} | {t_fuse:.3f} | {removed.method} | {'yes' if same else 'NO'} |")


if __name__ == "__main__":
    main()
