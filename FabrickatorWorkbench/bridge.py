"""Geometry across the border between FreeCAD and ``core``.

Shapes cross between FreeCAD's OpenCascade and cadquery's (OCP) as BREP
text, never as objects: the two are different builds of OpenCascade in one
process.  Meshes cross as arrays.  The Source of a Fabrication reaches the
core as a file, because :func:`core.pipeline.run` reads a path: a Part
shape as ``.brep`` (exact, with its placement), a mesh as binary STL.
"""

from __future__ import annotations

import io
import os
import shutil
import tempfile

import FreeCAD as App
import Mesh
import Part


def source_kind(obj) -> str | None:
    """``"shape"`` for an object with a solid, ``"mesh"`` for a mesh feature, else None."""
    if obj is None:
        return None
    mesh = getattr(obj, "Mesh", None)
    if mesh is not None and hasattr(mesh, "CountFacets"):
        return "mesh" if mesh.CountFacets > 0 else None
    shape = getattr(obj, "Shape", None)
    if shape is not None and not shape.isNull() and len(shape.Solids) > 0:
        return "shape"
    return None


def write_source(obj, folder: str) -> str:
    """Write the Source ``obj`` into ``folder`` as the core reads it; the file's path.

    A shape is written as ``source.brep`` (its solids, with the object's
    placement), a mesh feature as ``source.stl`` (with its placement).
    Raises ValueError when the object has neither solid nor mesh.
    """
    kind = source_kind(obj)
    if kind == "mesh":
        path = os.path.join(folder, "source.stl")
        obj.Mesh.write(path)
        return path
    if kind == "shape":
        path = os.path.join(folder, "source.brep")
        shape = obj.Shape
        solids = shape.Solids
        (solids[0] if len(solids) == 1 else _compound(solids)).exportBrep(path)
        return path
    raise ValueError(f"{obj.Label if obj is not None else 'nothing'} has no solid and no mesh")


def _compound(shapes):
    return Part.makeCompound(shapes)


def shapes_to_brep(shapes) -> str:
    """BREP text of FreeCAD ``shapes`` (a compound of them, in their order, in the
    document's coordinates): how faces or solids reach :mod:`core`."""
    return _compound(list(shapes)).exportBrepToString()


def occ_to_part(occ_shape):
    """A FreeCAD ``Part.Shape`` from an OCP (cadquery) shape, through BREP text."""
    from OCP.BRepTools import BRepTools

    stream = io.BytesIO()
    BRepTools.Write_s(getattr(occ_shape, "wrapped", occ_shape), stream)
    shape = Part.Shape()
    shape.importBrepFromString(stream.getvalue().decode("ascii"))
    return shape


def part_to_occ(shape):
    """An OCP ``TopoDS_Shape`` from a FreeCAD ``Part.Shape``, through BREP text."""
    from OCP.BRep import BRep_Builder
    from OCP.BRepTools import BRepTools
    from OCP.TopoDS import TopoDS_Shape

    out = TopoDS_Shape()
    BRepTools.Read_s(out, io.BytesIO(shape.exportBrepToString().encode("ascii")), BRep_Builder())
    return out


def trimesh_to_part(mesh):
    """A faceted closed ``Part.Shape`` (a solid when the mesh is closed) of a trimesh mesh.

    One planar face per triangle, sewn: the exact result of a Boolean on a
    mesh model is a mesh, and this is that mesh as a FreeCAD shape.
    """
    fc = Mesh.Mesh()
    fc.addFacets(mesh.triangles.tolist())
    shape = Part.Shape()
    shape.makeShapeFromMesh(fc.Topology, 0.01)
    shell = Part.Shell(shape.Faces)
    return Part.Solid(shell) if shell.isClosed() else shell


def part_to_trimesh(shape, tolerance: float = 0.05):
    """A watertight trimesh mesh (model mm) of a closed ``Part.Shape``, tessellated by OCP."""
    from core.parts.brick_solids import to_trimesh

    return to_trimesh(part_to_occ(shape), tolerance=tolerance)


def vector(values) -> App.Vector:
    """A FreeCAD vector from three numbers."""
    return App.Vector(float(values[0]), float(values[1]), float(values[2]))


def snapshot(fab) -> str:
    """A zip of the core's iteration snapshot of ``fab`` (in a temporary folder of its
    own, which the caller removes)."""
    from core import result

    with tempfile.TemporaryDirectory(prefix="fabrickator-snap-") as folder:
        result.snapshot(fab, folder)
        holder = tempfile.mkdtemp(prefix="fabrickator-snapshot-")
        return shutil.make_archive(os.path.join(holder, "iteration"), "zip", folder)
