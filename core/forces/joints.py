"""The joints of the force model: LEGO's clutch, friction and strength, and each body's mass.

What one stud contact point holds (:data:`CLUTCH_N`, :data:`CONTACT_RADIUS`), what a
brick bends (:func:`bending_capacity_nmm`), what the table does (:data:`TABLE_FRICTION`),
and how much a printed part weighs (:func:`printed_mass_g`).
"""

from __future__ import annotations

import math

import numpy as np


#: Acceleration of gravity, m/s^2.
G = 9.81


#: Default clutch: the tension one stud contact point holds, N (StableLego's T = 100 g).
CLUTCH_N = 0.98


#: Distance of a stud's contact points from its axis, in studs (8 mm), the one fitted
#: constant: with :data:`CLUTCH_N`, the catalog weights and a baseplate, StableLego's 2x4
#: staircase offset by two studs (stands at 19 levels, falls at 20) puts it below 0.2305, and
#: its 47-stud stick of 1-wide bricks (three 1x4 at the tip, a 1x2 propping its second
#: brick) above 0.2025; tests/core/test_stablelego.py checks every photographed build.
CONTACT_RADIUS = 0.215


#: Friction coefficient of ABS on a table top.
TABLE_FRICTION = 0.4


#: A build stands on a table only in the pose it was built in: one that would settle
#: leaning onto lower points (more than this, degrees: rounding) tips over.
MAX_TILT_DEG = 0.5


#: ABS tensile strength used for a part's bending strength, N/mm^2 (MPa).
ABS_STRENGTH_MPA = 40.0


#: LEGO wall and top thickness, mm (DESIGN.md dimensions: walls 1.2-1.5, top 1.0).
WALL_MM = 1.2


TOP_MM = 1.0


#: Grounds a layout can stand on.
GROUNDS = ("table", "baseplate")


#: Utilisation above which a joint counts as failing (numerical slack of the LP).
FAIL_ABOVE = 1.0 + 1e-6


_DIAG = math.sqrt(0.5)


def contact_directions(size_x: np.ndarray, size_y: np.ndarray, a: np.ndarray, b: np.ndarray,
                       printed: np.ndarray) -> np.ndarray:
    """Unit directions (n, 4, 2) from each stud's axis to its contact points, NaN where unused.

    The stud is at local position (``a``, ``b``) under a part of footprint
    (``size_x``, ``size_y``) studs.  A 1-wide part or a printed socket grips
    it all round (+x, -x, +y, -y); a 2-wide part by the outer wall across
    the part, and along it by the end wall at an end or the tube between it
    and the next stud (diagonally, towards the part's centre line).
    """
    n = len(a)
    out = np.full((n, 4, 2), np.nan)
    ring = np.array([[1.0, 0.0], [-1.0, 0.0], [0.0, 1.0], [0.0, -1.0]])
    round_ = printed | (np.minimum(size_x, size_y) < 2)
    out[round_] = ring
    for long_x in (True, False):
        sel = ~round_ & ((size_x >= size_y) == long_x)
        if not sel.any():
            continue
        along, across = (a[sel], b[sel]) if long_x else (b[sel], a[sel])
        length = size_x[sel] if long_x else size_y[sel]
        side = np.where(across == 0, -1.0, 1.0)      # the outer wall beside the stud
        inward = -side                                # towards the centre line (tubes)
        d = np.zeros((sel.sum(), 4, 2))
        d[:, 3] = np.nan
        # (along, across) components, then swapped into (x, y) for a part long in y
        d[:, 0] = np.stack([np.zeros_like(side), side], axis=1)
        minus_end = along == 0
        d[:, 1] = np.where(minus_end[:, None], [[-1.0, 0.0]],
                           np.stack([np.full_like(side, -_DIAG), _DIAG * inward], axis=1))
        plus_end = along == length - 1
        d[:, 2] = np.where(plus_end[:, None], [[1.0, 0.0]],
                           np.stack([np.full_like(side, _DIAG), _DIAG * inward], axis=1))
        if not long_x:
            d = d[:, :, ::-1]
        out[sel] = d
    return out


def section_modulus_mm3(width_mm: float, height_mm: float) -> float:
    """Elastic section modulus (mm^3) of a LEGO part's cross-section: a top of
    :data:`TOP_MM` over two side walls of :data:`WALL_MM`, ``width_mm`` wide and
    ``height_mm`` tall (the hollow underside's tubes ignored: on the safe side)."""
    top_a = width_mm * TOP_MM
    wall_h = height_mm - TOP_MM
    wall_a = 2 * WALL_MM * wall_h
    top_y, wall_y = height_mm - TOP_MM / 2, wall_h / 2
    area = top_a + wall_a
    ybar = (top_a * top_y + wall_a * wall_y) / area
    inertia = (width_mm * TOP_MM ** 3 / 12 + top_a * (top_y - ybar) ** 2
               + 2 * WALL_MM * wall_h ** 3 / 12 + wall_a * (wall_y - ybar) ** 2)
    return inertia / max(ybar, height_mm - ybar)


def bending_capacity_nmm(across_studs: int, layers: int, cell=(8.0, 8.0, 3.2)) -> float:
    """Bending moment (N mm) a LEGO part ``across_studs`` wide and ``layers`` plates tall
    takes across a section: :data:`ABS_STRENGTH_MPA` times :func:`section_modulus_mm3`."""
    return ABS_STRENGTH_MPA * section_modulus_mm3(across_studs * cell[0] - 0.2, layers * cell[2])


def printed_mass_g(volume_mm3: float, area_mm2: float, profile: dict[str, str] | None = None) -> float:
    """Mass (g) of a printed part of ``volume_mm3`` and surface ``area_mm2`` as the slicer
    prints it: a shell of the profile's perimeters times their extrusion width all round,
    the rest filled at the profile's ``fill_density``, in its ``filament_density``
    (PLA 1.24 g/cm^3, 2 perimeters of 0.45 mm, 15 % infill without a profile)."""
    cfg = profile or {}

    def number(key: str, default: float) -> float:
        try:
            return float(str(cfg.get(key, default)).rstrip("%").split(",")[0])
        except ValueError:
            return default
    density = number("filament_density", 1.24)
    fill = number("fill_density", 15.0) / 100.0
    shell_mm = number("perimeters", 2) * number("perimeter_extrusion_width", 0.45)
    shell = min(volume_mm3, area_mm2 * shell_mm)
    return density * (shell + fill * (volume_mm3 - shell)) / 1000.0


def solid_pla_g(size_mm: np.ndarray) -> float:
    """Mass (g) of a box of solid PLA (1.24 g/cm^3): a printed brick without its part."""
    return 1.24 * float(np.prod(size_mm)) / 1000.0
