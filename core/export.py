"""Export of printed parts: ``parts/<id>.stl`` and ``.step`` per part, one 3MF plate.

The STL is the part's watertight mesh.  The STEP is the part's B-rep for
B-rep input; for mesh input (whose exact result is a mesh) it is a faceted
solid built from that mesh, one planar face per triangle.  The plate
``parts/plate.3mf`` holds every part laid flat (upright, its underside on the bed,
see :func:`lay_flat`) and placed in a row with :data:`SPACING_MM`
between neighbours, ready to slice.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import trimesh
from OCP.BRep import BRep_Builder
from OCP.BRepBuilderAPI import (BRepBuilderAPI_MakeEdge, BRepBuilderAPI_MakeFace,
                                BRepBuilderAPI_MakeSolid, BRepBuilderAPI_MakeVertex)
from OCP.gp import gp_Dir, gp_Pln, gp_Pnt
from OCP.IFSelect import IFSelect_RetDone
from OCP.Interface import Interface_Static
from OCP.STEPControl import STEPControl_AsIs, STEPControl_Writer
from OCP.TopoDS import TopoDS_Shell, TopoDS_Wire

from core.errors import InputError
from core.printed import PrintedPart

#: Gap (mm) between parts on the 3MF plate.
SPACING_MM = 5.0


def lay_flat(mesh: trimesh.Trimesh) -> trimesh.Trimesh:
    """A copy of ``mesh`` standing upright as the brick stands (studs up, the
    underside on the bed, which is how studs print round) with its min corner at 0."""
    out = mesh.copy()
    out.apply_translation(-out.bounds[0])
    return out


def plate(parts: list[PrintedPart]) -> list[trimesh.Trimesh]:
    """The parts' meshes laid flat and placed in a row along x, SPACING_MM apart."""
    out, x = [], 0.0
    for p in parts:
        m = lay_flat(p.mesh)
        m.apply_translation([x, 0.0, 0.0])
        x += float(m.extents[0]) + SPACING_MM
        out.append(m)
    return out


def write_step(shape, path: str | os.PathLike) -> None:
    """Write an OCP shape as a STEP (AP214) file in mm; InputError when OCC refuses."""
    Interface_Static.SetCVal_s("write.step.unit", "MM")
    writer = STEPControl_Writer()
    writer.Transfer(shape, STEPControl_AsIs)
    if writer.Write(str(path)) != IFSelect_RetDone:
        raise InputError(f"could not write the STEP file {path}")


def faceted_solid(mesh: trimesh.Trimesh):
    """An OCP solid with one planar face per triangle of the closed ``mesh``.

    The topology is built directly (one vertex per mesh vertex, one edge per
    mesh edge shared by its two triangles, each face on the plane of its
    triangle's outward normal), so no sewing is needed.  Its volume equals
    the mesh's; OCC's validity checker may still flag sliver triangles.
    """
    vertices = np.asarray(mesh.vertices, dtype=np.float64)
    verts = [BRepBuilderAPI_MakeVertex(gp_Pnt(*v)).Vertex() for v in vertices.tolist()]
    unique, inverse = np.unique(mesh.edges_sorted, axis=0, return_inverse=True)
    edges = [BRepBuilderAPI_MakeEdge(verts[a], verts[b]).Edge() for a, b in unique.tolist()]
    inverse = inverse.reshape(-1, 3)
    raw = mesh.edges.reshape(-1, 3, 2)
    reversed_ = raw[:, :, 0] > raw[:, :, 1]
    builder = BRep_Builder()
    shell = TopoDS_Shell()
    builder.MakeShell(shell)
    for corner, normal, idx, rev in zip(vertices[mesh.faces[:, 0]].tolist(),
                                        mesh.face_normals.tolist(), inverse.tolist(), reversed_.tolist()):
        wire = TopoDS_Wire()
        builder.MakeWire(wire)
        for e, r in zip(idx, rev):
            builder.Add(wire, edges[e].Reversed() if r else edges[e])
        wire.Closed(True)
        plane = gp_Pln(gp_Pnt(*corner), gp_Dir(*normal))
        builder.Add(shell, BRepBuilderAPI_MakeFace(plane, wire, True).Face())
    shell.Closed(True)
    return BRepBuilderAPI_MakeSolid(shell).Solid()


def export_parts(parts: list[PrintedPart], folder: str | os.PathLike) -> list[str]:
    """Write ``<id>.stl``, ``<id>.step`` per part and ``plate.3mf`` into ``folder``.

    Sets ``stl`` and ``step`` of each part to the paths relative to the
    folder's parent (``parts/P1.stl``); returns the names written.
    """
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    written = []
    for p in parts:
        stl, step = folder / f"{p.id}.stl", folder / f"{p.id}.step"
        p.mesh.export(stl)
        write_step(p.solid if p.solid is not None else faceted_solid(p.mesh), step)
        p.stl, p.step = f"{folder.name}/{stl.name}", f"{folder.name}/{step.name}"
        written += [stl.name, step.name]
    if parts:
        scene = trimesh.Scene()
        for p, m in zip(parts, plate(parts)):
            scene.add_geometry(m, node_name=p.id, geom_name=p.id)
        (folder / "plate.3mf").write_bytes(trimesh.exchange.threemf.export_3MF(scene))
        written.append("plate.3mf")
    return written
