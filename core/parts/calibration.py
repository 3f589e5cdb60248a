"""The calibration strip: printed studs and sockets in small steps of fit.

``python -m core calibration-strip --out DIR`` writes a strip to print on
the user's own printer and test against real LEGO, to find the two fit
settings of :class:`core.parts.interfaces.Fit`:

* ``calibration_strip.stl`` and ``calibration_strip.3mf``: one watertight
  solid in its print pose (flat side on the bed, studs up, no supports
  needed);
* ``README.txt``: how to print and read it.

The strip is a row of *columns*, one per value ``v`` (default -0.10 to
+0.20 mm in steps of 0.05: seven columns, under 20 minutes of printing, with
the defaults of both settings well inside).  A column is a printed cell exactly as the pipeline builds one: a
block of the cell's footprint (``PITCH - 2 * play``, 7.8 mm square) and
``socket_depth + roof`` high, with

* a **socket** opening downward on the strip's underside: a square hole
  ``4.8 + v`` wide between opposite walls, ``socket_depth`` deep, under a
  ``roof`` (printed as a short bridge, no support);
* a **stud** on top: a cylinder of diameter ``4.8 + v`` and ``stud_height``
  standing on that roof.

So column ``v`` tests ``stud_fit = v`` with its stud and ``socket_fit = v``
with its socket.  The columns stand :data:`GAP_MM` or more apart (a pitch
that is no multiple of 8 mm), so that no LEGO brick clamps two of them at
once: each value is tested alone.  A thin band along the strip joins them
into one solid and carries each column's value, embossed beside it.

Everything is in mm.
"""

from __future__ import annotations

import json
import math
import os
from dataclasses import dataclass, replace
from pathlib import Path

from core.errors import InputError
from core.parts.interfaces import LEGO_STUD_DIAMETER, PITCH, Fit

#: Default step between two columns' values (mm).
STEP_MM = 0.05
#: How far the default range reaches below the smaller and above the larger
#: of the two current fit settings (mm): the lowest value must be loose, the
#: highest too tight, so that the first one that clamps is found in between.
BELOW_MM, ABOVE_MM = 0.10, 0.15
#: The smallest step that means something on an FDM printer (mm).
MIN_STEP_MM = 0.01
#: At most this many columns (about 16 cm of strip with two-decimal labels).
MAX_COLUMNS = 13
#: Values are rounded to this many decimals (the labels show at most these).
DECIMALS = 3
#: Least free space between two neighbouring columns (mm).
GAP_MM = 2.5
#: The band that joins the columns: its width beside them, its thickness,
#: and how far it reaches into the columns' walls (so that the two join with
#: volume, not along a face; the sockets stay clear of it).
BAND_WIDTH_MM, BAND_THICKNESS_MM, BAND_OVERLAP_MM = 5.0, 1.2, 0.5
#: The values' text: font size, height of the raised letters, free space
#: between two labels along the strip.
LABEL_FONT_MM, LABEL_RAISE_MM, LABEL_GAP_MM = 3.5, 0.6, 2.0
#: Tessellation of the written mesh: chord deviation (mm) and angle (rad).
#: A stud's circle gets at least 2 pi / 0.065 = 97 sides, its corners on the
#: circle and its flats 0.001 mm inside it (the pipeline's mesh studs have 96),
#: far below the 0.05 mm steps the strip is about.
MESH_TOLERANCE_MM, MESH_ANGLE_RAD = 0.005, 0.065

STL_NAME = "calibration_strip.stl"
THREEMF_NAME = "calibration_strip.3mf"
README_NAME = "README.txt"


@dataclass(frozen=True)
class Strip:
    """A built calibration strip.

    ``values`` are the columns' values left to right (mm), ``fit`` the
    settings its heights come from, ``pitch`` the distance between columns,
    ``solid`` the B-rep (OCP ``TopoDS_Shape``) and ``mesh`` its watertight
    tessellation, both in the print pose: the underside on z = 0, the first
    column centred at x = pitch / 2, the columns' blocks at y in [0, 7.8], the band
    with the labels beside them at y > 7.8.
    """

    values: tuple[float, ...]
    fit: Fit
    pitch: float
    solid: object
    mesh: "trimesh.Trimesh"


def cell_mm(fit: Fit = Fit()) -> float:
    """Side of a column's block: the cell's footprint, ``PITCH - 2 * play`` (7.8 mm)."""
    return PITCH - 2 * fit.play


def default_range(fit: Fit = Fit()) -> tuple[float, float]:
    """The default (from, to) of the strip around ``fit``'s two settings: from
    BELOW_MM under the smaller to ABOVE_MM over the larger (-0.10 .. +0.20 mm
    for the defaults)."""
    low, high = min(fit.stud_fit, fit.socket_fit), max(fit.stud_fit, fit.socket_fit)
    return round(low - BELOW_MM, DECIMALS), round(high + ABOVE_MM, DECIMALS)


def column_values(start: float | None = None, stop: float | None = None,
                  step: float | None = None, fit: Fit = Fit()) -> tuple[float, ...]:
    """The columns' values: ``start``, ``start + step``, ... up to ``stop`` (included),
    rounded to DECIMALS; unset ends come from :func:`default_range`, an unset step is
    STEP_MM.

    Raises InputError (one line) when a number is not finite, the step is below
    MIN_STEP_MM, the range is empty, it needs more than MAX_COLUMNS columns, or a
    value is not a valid ``stud_fit``/``socket_fit`` (:meth:`Fit.check`).
    """
    low, high = default_range(fit)
    start = low if start is None else start
    stop = high if stop is None else stop
    step = STEP_MM if step is None else step
    for name, value in (("from", start), ("to", stop), ("step", step)):
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
            raise InputError(f"--{name} {value!r} must be a finite number of mm")
    if step <= 0:
        raise InputError(f"--step {step:g} mm must be positive")
    if step < MIN_STEP_MM:
        raise InputError(f"--step {step:g} mm is finer than a printer can show "
                         f"(at least {MIN_STEP_MM:g} mm)")
    column_fit(fit, start)
    column_fit(fit, stop)
    if stop < start:
        raise InputError(f"the range --from {start:g} --to {stop:g} mm is empty")
    count = int(math.floor((stop - start) / step + 1e-6)) + 1
    if count > MAX_COLUMNS:
        raise InputError(f"--from {start:g} --to {stop:g} --step {step:g} mm makes {count} "
                         f"columns, more than {MAX_COLUMNS}: narrow the range or take a "
                         f"larger step")
    values = tuple(_tidy(start + n * step) for n in range(count))
    for value in values:
        column_fit(fit, value)
    return values


def column_fit(fit: Fit, value: float) -> Fit:
    """``fit`` with both settings at ``value``: the fit of that column (checked)."""
    try:
        return replace(fit, stud_fit=value, socket_fit=value).check()
    except InputError as err:
        raise InputError(f"calibration value {value:+g} mm: {err}") from None


def label(value: float) -> str:
    """The text of a column's value: '+0.05', '-0.10', '0.00' (three decimals when needed)."""
    digits = 2 if abs(round(value, 2) - value) < 1e-9 else DECIMALS
    return f"{0.0:.{digits}f}" if abs(value) < 1e-9 else f"{value:+.{digits}f}"


def build_strip(values, fit: Fit = Fit()) -> Strip:
    """The strip with one column per value in ``values`` (mm, left to right), the
    studs' and sockets' heights from ``fit``.

    Promises: one valid solid; column n's stud is a cylinder of diameter
    ``4.8 + values[n]`` and ``fit.stud_height`` on the top face at
    z = ``socket_depth + roof``, its socket a square hole ``4.8 + values[n]``
    wide from z = 0 up to ``socket_depth``, both centred on the column's
    block; its label is raised LABEL_RAISE_MM on the band beside it.  Raises
    InputError for a value :func:`column_fit` refuses (the user's), ValueError
    for an empty ``values`` (:func:`strip_values` never gives one) and
    RuntimeError when the strip does not come out as one valid solid.
    """
    import cadquery as cq

    from core.parts.brick_solids import to_trimesh

    values = tuple(_tidy(v) for v in values)
    if not values:
        raise ValueError("the calibration strip needs at least one value")
    fits = [column_fit(fit, v) for v in values]
    cell = cell_mm(fit)
    height = fit.socket_depth + fit.roof
    texts = [_text_solid(label(v), LABEL_RAISE_MM) for v in values]
    pitch = _pitch(max(cell + GAP_MM, max(t.BoundingBox().xlen for t in texts) + LABEL_GAP_MM))
    margin = (pitch - cell) / 2
    band = _box(0.0, cell - BAND_OVERLAP_MM, 0.0, len(values) * pitch, cell + BAND_WIDTH_MM,
                BAND_THICKNESS_MM)
    cells, labels = [], []
    for n, f in enumerate(fits):
        cx, cy = margin + n * pitch + cell / 2, cell / 2
        block = _box(cx - cell / 2, 0.0, 0.0, cx + cell / 2, cell, height)
        w = f.socket_width
        cells.append(block.cut(_box(cx - w / 2, cy - w / 2, -1.0, cx + w / 2, cy + w / 2,
                                    f.socket_depth)))
        cells.append(cq.Solid.makeCylinder(f.stud_diameter / 2, f.stud_height,
                                           cq.Vector(cx, cy, height), cq.Vector(0, 0, 1)))
        labels.append(_placed(texts[n], cx, cell + BAND_WIDTH_MM / 2, BAND_THICKNESS_MM))
    # the letters stand on the band's top face: a glue fuse joins them there, fast
    solid = band.fuse(*cells).fuse(*labels, glue=True)
    solid = solid.clean()
    if len(solid.Solids()) != 1 or not solid.isValid():
        raise RuntimeError("the calibration strip did not come out as one valid solid")
    shape = solid.Solids()[0].wrapped
    mesh = to_trimesh(shape, MESH_TOLERANCE_MM, MESH_ANGLE_RAD)
    return Strip(values, fit, pitch, shape, mesh)


def readme(strip: Strip) -> str:
    """README.txt of ``strip``: what it is, how to print it, how to read it, where
    the values go (``--stud-fit``, ``--socket-fit``, the FreeCAD preferences)."""
    f, values, d = strip.fit, strip.values, LEGO_STUD_DIAMETER
    listing = ", ".join(label(v) for v in values)
    tight = label(values[-1])
    loose = label(values[0])
    step = label(values[1] - values[0]).lstrip("+") if len(values) > 1 else None
    size = strip.mesh.bounds[1] - strip.mesh.bounds[0]
    steps = f" in steps of {step} mm" if step else ""
    return f"""Fabrickator calibration strip: stud and socket fit for your printer
=====================================================================

{STL_NAME} (or {THREEMF_NAME}, the same strip) is {len(values)} columns of
printed LEGO interface, one per value from {loose} to {tight} mm{steps}.
Left to right, as the numbers read: {listing}.
Each column is a printed cell exactly as Fabrickator builds one:

  * on top, a stud of {d:g} + value mm diameter, {f.stud_height:g} mm high;
  * underneath, a square socket {d:g} + value mm between opposite walls,
    {f.socket_depth:g} mm deep under a {f.roof:g} mm roof.

The strip is {size[0]:.0f} x {size[1]:.0f} x {size[2]:.1f} mm.

Printing
--------
Print it as it lies (flat side on the bed, studs up, no supports), with the
printer, nozzle, filament and layer height you print your parts with: the
fit it finds is the fit of that set-up.

Reading it
----------
You need a real LEGO 1x1 plate (3024), or a 1x2 plate (3023).

Studs, --stud-fit: press the plate onto each stud, starting at {loose} (the
thinnest stud) and going up.  Hold a 1x2 plate across the strip, its empty
half over the strip's edge.  Take the FIRST value at which the plate clamps
firmly: it holds when you turn the strip upside down, comes off with a
pull, and nothing cracks or whitens.

Sockets, --socket-fit: press the stud of the plate into each socket from
below, starting at {tight} (the widest socket) and going down: a smaller
value is a tighter socket.  A 1x2 plate's other stud points away from the
strip, past the edge without the numbers.  Take the FIRST value at which
the stud clamps firmly (holds the strip upside down, comes off with a pull)
without cracking the walls.

If even the last column is loose, or the first one is already tight, print
another strip further along, e.g.
  python -m core calibration-strip --from 0.20 --to 0.50 --out DIR

Using the values
----------------
  python -m core fabricate MODEL --stud-fit STUD --socket-fit SOCKET --out DIR

or save them for your printer and filament, used whenever you name that
printer (--printer NAME, or --slicer-config FILE.ini):
  python -m core save-fit --printer NAME --stud-fit STUD --socket-fit SOCKET

In FreeCAD: Edit > Preferences > Fabrickator, "Stud fit" and "Socket fit"
(for new Fabrications); an existing Fabrication has its own StudFit and
SocketFit properties (also in the "Lay out" dialog).  Defaults: stud fit
{label(Fit.stud_fit)}, socket fit {label(Fit.socket_fit)} mm.
"""


def write_strip(out, values=None, fit: Fit = Fit()) -> tuple[Strip, list[Path]]:
    """Build the strip (:func:`build_strip`; ``values`` default to :func:`column_values`
    around ``fit``) and write STL_NAME, THREEMF_NAME and README_NAME into the folder
    ``out``; returns the strip and the three paths.

    The values are checked, and the folder (:class:`core.io.output_dir.OutputFolder`:
    new, empty or an earlier strip's, made when missing, writable, not being written
    by another run) before anything is built.  The files are written into a
    temporary folder beside ``out`` that replaces it whole at the end, so a folder
    with the strip's files is complete.  Raises InputError when ``out`` cannot be
    made or written or holds other files, or for values :func:`build_strip` refuses.
    """
    import trimesh

    from core.io import output_dir

    values = column_values(fit=fit) if values is None else tuple(values)
    for value in values:
        column_fit(fit, value)
    names = (STL_NAME, THREEMF_NAME, README_NAME)
    with output_dir.OutputFolder(out, earlier=output_dir.files_output(*names)) as folder:
        strip = build_strip(values, fit)
        contents = (trimesh.exchange.stl.export_stl(strip.mesh),
                    trimesh.exchange.threemf.export_3MF(strip.mesh),
                    readme(strip).encode("utf-8"))
        for name, data in zip(names, contents):
            (folder.temp / name).write_bytes(data)
        folder.install()
    return strip, [folder.out / name for name in names]


def _pitch(least: float) -> float:
    """The distance between columns: ``least``, or more where that is within GAP_MM of a
    multiple of LEGO's 8 mm pitch (a brick could then clamp two columns at once)."""
    nearest = PITCH * round(least / PITCH)
    return nearest + GAP_MM if abs(least - nearest) < GAP_MM else least


def _tidy(value: float) -> float:
    """``value`` rounded to DECIMALS, without a negative zero."""
    return round(float(value), DECIMALS) + 0.0


def _box(x0, y0, z0, x1, y1, z1) -> "cq.Solid":
    """The box between the corners (x0, y0, z0) and (x1, y1, z1)."""
    import cadquery as cq

    return cq.Solid.makeBox(x1 - x0, y1 - y0, z1 - z0, cq.Vector(x0, y0, z0))


def _text_solid(text: str, height: float) -> cq.Shape:
    """``text`` at LABEL_FONT_MM, bold, centred on the origin, extruded ``height`` up
    (the font and set-up of the printed parts' engraved ids, :func:`core.parts.engraving.text_shape`)."""
    import cadquery as cq

    from core.parts.engraving import text_shape

    return text_shape(text, LABEL_FONT_MM, cq.Plane.XY(), height)


def _placed(shape: cq.Shape, cx: float, cy: float, z: float) -> cq.Shape:
    """``shape`` moved so that its bounding box is centred on (cx, cy) and starts at z."""
    import cadquery as cq

    box = shape.BoundingBox()
    return shape.translate(cq.Vector(cx - box.center.x, cy - box.center.y, z - box.zmin))


#: File name of the fits saved per printer and filament, in :func:`fits_file`'s folder.
FITS_NAME = "fits.json"


def fits_file() -> Path:
    """Where the fits found with the strip are saved: ``$XDG_CONFIG_HOME/fabrickator/fits.json``
    (when XDG_CONFIG_HOME is an absolute path), else ``~/.config/fabrickator/fits.json``."""
    base = os.environ.get("XDG_CONFIG_HOME", "")
    folder = Path(base) if os.path.isabs(base) else Path.home() / ".config"
    return folder / "fabrickator" / FITS_NAME


def saved_fits(path: str | os.PathLike | None = None) -> dict:
    """The saved fits, ``{printer: {filament: {"stud_fit": mm, "socket_fit": mm}}}``, of
    ``path`` (default :func:`fits_file`); empty when there is none.  Raises InputError
    naming the file when it is unreadable or not such a table."""
    path = Path(path or fits_file())
    if not path.exists():
        return {}
    try:
        table = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeError, ValueError) as exc:
        raise InputError(f"saved fits {path}: cannot read them ({getattr(exc, 'strerror', None) or exc})") from None
    ok = isinstance(table, dict) and all(
        isinstance(by, dict) and all(isinstance(v, dict) and {"stud_fit", "socket_fit"} <= set(v)
                                     for v in by.values()) for by in table.values())
    if not ok:
        raise InputError(f"saved fits {path}: not a table of printer -> filament -> stud_fit, socket_fit")
    return table


def saved_fit(printer: str, filament: str, path: str | os.PathLike | None = None) -> Fit | None:
    """The fit saved for ``printer`` and ``filament`` (:func:`saved_fits`), or None."""
    entry = saved_fits(path).get(printer, {}).get(filament)
    if entry is None:
        return None
    return Fit(stud_fit=float(entry["stud_fit"]), socket_fit=float(entry["socket_fit"])).check()


def save_fit(printer: str, filament: str, fit: Fit, path: str | os.PathLike | None = None) -> Path:
    """Save ``fit`` (checked) for ``printer`` and ``filament`` into ``path`` (default
    :func:`fits_file`, its folder made when missing), keeping the other printers' fits;
    returns the file.  The file is replaced whole.  Raises InputError when it cannot
    be written."""
    fit.check()
    path = Path(path or fits_file())
    table = saved_fits(path)
    table.setdefault(printer, {})[filament] = {"stud_fit": float(fit.stud_fit),
                                               "socket_fit": float(fit.socket_fit)}
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        temp = path.with_name(path.name + ".tmp")
        temp.write_text(json.dumps(table, indent=2, sort_keys=True) + "\n", encoding="utf-8")
        os.replace(temp, path)
    except OSError as exc:
        raise InputError(f"cannot save the fit into {path}: {exc.strerror or exc}") from None
    return path
