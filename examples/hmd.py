"""A head-mounted display body: Fabrickator's bundled demo model.

Like the HMD of the faBrickation paper (and a Cardboard-style VR headset), it
is a hollow box open on the face side, closed by a front plate where the
screen sits, with an internal lens plate that carries two lens mounts: the
precision features a designer marks high-res, while the rest of the body is
built from LEGO.

Coordinates (mm): x across the face (width), y from the face (y = 0) to
the front plate, z up.  ``build_hmd()`` returns the solid as a cadquery
Workplane; ``python examples/hmd.py OUTDIR`` writes OUTDIR/hmd.step and
OUTDIR/hmd.stl.
"""

from __future__ import annotations

import sys
from pathlib import Path

import cadquery as cq

#: Outer size of the body: width (x), depth from face to front (y), height (z).
BODY_WIDTH = 150.0
BODY_DEPTH = 80.0
BODY_HEIGHT = 90.0
#: Radius of the rounded vertical and top/bottom edges of the outer body.
CORNER_RADIUS = 8.0
#: Wall thickness of the shell (sides, top, bottom and front plate).
WALL = 3.5

#: Distance of the lens plate's face-side surface from the face (y), and its thickness.
LENS_PLATE_Y = 32.0
LENS_PLATE_THICKNESS = 3.0
#: Interpupillary distance: lens centre to lens centre.
IPD = 63.0
#: Height of the lens centres above the bottom of the body.
LENS_CENTRE_Z = 48.0
#: Diameter of the lenses (the seat bore) and the radial step the lens rests on.
LENS_DIAMETER = 37.0
LENS_SEAT_STEP = 2.0
#: Depth of the lens seat (the bore of full lens diameter), from the boss top.
LENS_SEAT_DEPTH = 3.0
#: Lens mount ring: wall around the lens seat and how far it stands out
#: from the lens plate towards the face.
RING_WALL = 3.0
RING_HEIGHT = 6.0

#: Nose cut-out at the bottom centre of the face side: width and height of
#: the arch, and how deep (y) it reaches, through the lens plate.
NOSE_WIDTH = 36.0
NOSE_HEIGHT = 30.0
NOSE_DEPTH = LENS_PLATE_Y + LENS_PLATE_THICKNESS + 2.0

#: STL tessellation: linear deflection in mm, angular deflection in radians.
STL_TOLERANCE = 0.05
STL_ANGULAR_TOLERANCE = 0.1


def _shell() -> cq.Workplane:
    """The rounded box, hollowed with WALL-thick walls, open on the face side (y = 0)."""
    body = (cq.Workplane("XY")
            .box(BODY_WIDTH, BODY_DEPTH, BODY_HEIGHT, centered=(True, False, False))
            .edges("|Y").fillet(CORNER_RADIUS))
    return body.faces("<Y").shell(-WALL)


def _lens_plate() -> cq.Workplane:
    """The plate across the body at LENS_PLATE_Y (the body's outer profile, so it
    fuses with the shell flush), with two ring bosses towards the face."""
    plate = (cq.Workplane("XY", origin=(0, LENS_PLATE_Y, 0))
             .box(BODY_WIDTH, LENS_PLATE_THICKNESS, BODY_HEIGHT, centered=(True, False, False))
             .edges("|Y").fillet(CORNER_RADIUS))
    centres = [(-IPD / 2, LENS_CENTRE_Z), (IPD / 2, LENS_CENTRE_Z)]
    ring_d = LENS_DIAMETER + 2 * RING_WALL
    rings = (cq.Workplane("XZ", origin=(0, LENS_PLATE_Y, 0))
             .pushPoints(centres).circle(ring_d / 2).extrude(RING_HEIGHT))
    return plate.union(rings)


def _lens_bores(plate_and_rings: cq.Workplane) -> cq.Workplane:
    """Cut the lens seats (full lens diameter) and the smaller apertures through the plate."""
    centres = [(-IPD / 2, LENS_CENTRE_Z), (IPD / 2, LENS_CENTRE_Z)]
    face_side = LENS_PLATE_Y - RING_HEIGHT
    seats = (cq.Workplane("XZ", origin=(0, face_side + LENS_SEAT_DEPTH, 0))
             .pushPoints(centres).circle(LENS_DIAMETER / 2).extrude(LENS_SEAT_DEPTH))
    aperture = LENS_DIAMETER - 2 * LENS_SEAT_STEP
    holes = (cq.Workplane("XZ", origin=(0, LENS_PLATE_Y + LENS_PLATE_THICKNESS + 1.0, 0))
             .pushPoints(centres).circle(aperture / 2)
             .extrude(LENS_PLATE_THICKNESS + RING_HEIGHT + 2.0))
    return plate_and_rings.cut(seats).cut(holes)


def _nose_cut() -> cq.Workplane:
    """An arch-shaped prism at the bottom centre, from the face to NOSE_DEPTH."""
    r = NOSE_WIDTH / 2
    arch = (cq.Workplane("XZ", origin=(0, NOSE_DEPTH, 0))
            .moveTo(-r, -1.0).lineTo(r, -1.0).lineTo(r, NOSE_HEIGHT - r)
            .threePointArc((0, NOSE_HEIGHT), (-r, NOSE_HEIGHT - r)).close())
    return arch.extrude(NOSE_DEPTH + 1.0)


def build_hmd() -> cq.Workplane:
    """The HMD body as one valid solid, sized BODY_WIDTH x BODY_DEPTH x BODY_HEIGHT mm.

    Shell open at the face (y = 0) with a WALL-thick front plate at y =
    BODY_DEPTH, a lens plate inside carrying two lens mounts (ring bosses of
    LENS_DIAMETER seats with a LENS_SEAT_STEP step, IPD apart) and a nose
    cut-out through the bottom and the lens plate.
    """
    lens_plate = _lens_bores(_lens_plate())
    body = _shell().union(lens_plate).cut(_nose_cut()).clean()
    solids = body.solids().vals()
    if len(solids) != 1 or not solids[0].isValid():
        raise RuntimeError(f"HMD model is not one valid solid ({len(solids)} solids)")
    return body


def export_hmd(out_dir: str | Path) -> tuple[Path, Path]:
    """Build the body and write ``hmd.step`` and ``hmd.stl`` into ``out_dir``; returns their paths."""
    from cadquery import exporters

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    solid = build_hmd().val()
    step, stl = out / "hmd.step", out / "hmd.stl"
    exporters.export(solid, str(step), exportType="STEP")
    exporters.export(solid, str(stl), exportType="STL", tolerance=STL_TOLERANCE,
                     angularTolerance=STL_ANGULAR_TOLERANCE)
    return step, stl


def main(argv: list[str]) -> int:
    """Command line: ``python examples/hmd.py OUTDIR``."""
    if len(argv) != 1:
        print("usage: python examples/hmd.py OUTDIR", file=sys.stderr)
        return 2
    for path in export_hmd(argv[0]):
        print(path)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
