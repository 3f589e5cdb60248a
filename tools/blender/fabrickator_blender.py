"""Fabrickator exporter for Blender: write the edited object as STL on leaving Edit Mode.

The faBrickation paper's Blender plug-in sent each new version of the model
to faBrickator when the user left edit mode.  This add-on does the same
through a watched folder: when the active mesh object goes from Edit Mode
back to Object Mode, its evaluated mesh (modifiers applied, world
transform applied, scaled to millimetres) is written as a binary STL
``<folder>/<object name>.stl``.  The file is written aside as a hidden
``.<name>.stl.part`` and renamed into place, so a watcher never sees half a
file.  Run ``python -m core watch <folder> --out <dir>`` (or the FreeCAD
workbench's watch command) on the same folder.

Install: Edit > Preferences > Add-ons > Install..., pick this file, enable
"Fabrickator export", set the folder (and millimetres per Blender unit:
1000 for the default metre scene, 1 when the scene is modelled in mm).
The panel "Fabrickator" in the 3D view's sidebar exports on demand too.

Works without Blender's STL operator (which moved between Blender 3 and
4): the STL is written here from the evaluated mesh's loop triangles.
"""

from __future__ import annotations

import os
import struct

import bpy
import numpy as np
from bpy.props import BoolProperty, FloatProperty, StringProperty

bl_info = {
    "name": "Fabrickator export",
    "author": "Fabrickator",
    "version": (1, 0, 0),
    "blender": (2, 93, 0),
    "location": "View3D > Sidebar > Fabrickator",
    "description": "Exports the edited object as STL into a watched folder on leaving Edit Mode",
    "category": "Import-Export",
}

#: Mode names Blender reports (``bpy.context.mode``) for mesh edit mode and object mode.
EDIT_MODE = "EDIT_MESH"
OBJECT_MODE = "OBJECT"


def _prefs():
    """This add-on's preferences, or None when it is not registered as an add-on."""
    addon = bpy.context.preferences.addons.get(__name__)
    return addon.preferences if addon else None


def triangles_mm(obj, mm_per_unit: float = 1000.0) -> np.ndarray:
    """The world-space triangles (n, 3, 3) of ``obj``'s evaluated mesh
    (modifiers applied) in mm, from its loop triangles."""
    depsgraph = bpy.context.evaluated_depsgraph_get()
    evaluated = obj.evaluated_get(depsgraph)
    mesh = evaluated.to_mesh()
    try:
        mesh.calc_loop_triangles()
        co = np.empty(len(mesh.vertices) * 3, dtype=np.float64)
        mesh.vertices.foreach_get("co", co)
        index = np.empty(len(mesh.loop_triangles) * 3, dtype=np.int64)
        mesh.loop_triangles.foreach_get("vertices", index)
        matrix = np.array(obj.matrix_world, dtype=np.float64)
        points = (co.reshape(-1, 3) @ matrix[:3, :3].T + matrix[:3, 3]) * mm_per_unit
        return points[index.reshape(-1, 3)]
    finally:
        evaluated.to_mesh_clear()


def write_stl(path: str, tris: np.ndarray, name: str = "fabrickator") -> None:
    """Write the triangles (n, 3, 3) as a binary STL at ``path``: written aside
    as a hidden ``.<name>.part`` file, then renamed into place."""
    folder, base = os.path.split(path)
    tmp = os.path.join(folder, "." + base + ".part")
    tris = np.asarray(tris, dtype=np.float64).reshape(-1, 3, 3)
    normal = np.cross(tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0])
    length = np.linalg.norm(normal, axis=1, keepdims=True)
    normal = np.divide(normal, length, out=np.zeros_like(normal), where=length > 0)
    record = np.zeros(len(tris), dtype=[("normal", "<f4", 3), ("corners", "<f4", (3, 3)),
                                        ("attribute", "<u2")])
    record["normal"], record["corners"] = normal, tris
    header = name.encode("ascii", "replace")[:80].ljust(80, b" ")
    with open(tmp, "wb") as f:
        f.write(header + struct.pack("<I", len(tris)) + record.tobytes())
    os.replace(tmp, path)


def export_object(obj, folder: str, mm_per_unit: float = 1000.0) -> str:
    """Export mesh object ``obj`` as ``<folder>/<name>.stl``; returns the path."""
    if obj is None or obj.type != "MESH":
        raise ValueError("Fabrickator exports mesh objects only")
    folder = bpy.path.abspath(folder)
    if not os.path.isdir(folder):
        raise ValueError(f"Fabrickator folder {folder!r} does not exist")
    safe = "".join(ch if ch.isalnum() or ch in "-_" else "_" for ch in obj.name) or "object"
    path = os.path.join(folder, safe + ".stl")
    write_stl(path, triangles_mm(obj, mm_per_unit), name=obj.name)
    return path


class _ModeTracker:
    """Remembers the last mode so a change from Edit Mode to Object Mode is seen once."""

    last = None


def on_depsgraph_update(scene, depsgraph=None):
    """Handler: export the active object when the user has just left Edit Mode."""
    mode = bpy.context.mode
    left_edit = _ModeTracker.last == EDIT_MODE and mode == OBJECT_MODE
    _ModeTracker.last = mode
    prefs = _prefs()
    if not left_edit or prefs is None or not prefs.auto_export or not prefs.folder:
        return
    obj = bpy.context.view_layer.objects.active
    if obj is None or obj.type != "MESH":
        return
    try:
        path = export_object(obj, prefs.folder, prefs.mm_per_unit)
        print(f"Fabrickator: exported {obj.name} to {path}")
    except (OSError, ValueError) as err:
        print(f"Fabrickator: export failed: {err}")


class FabrickatorPreferences(bpy.types.AddonPreferences):
    bl_idname = __name__

    folder: StringProperty(name="Watched folder", subtype="DIR_PATH", default="")
    mm_per_unit: FloatProperty(name="mm per Blender unit", default=1000.0, min=1e-6)
    auto_export: BoolProperty(name="Export on leaving Edit Mode", default=True)

    def draw(self, context):
        layout = self.layout
        layout.prop(self, "folder")
        layout.prop(self, "mm_per_unit")
        layout.prop(self, "auto_export")


class FABRICKATOR_OT_export(bpy.types.Operator):
    """Export the active object to the Fabrickator folder now"""

    bl_idname = "fabrickator.export"
    bl_label = "Export to Fabrickator"

    def execute(self, context):
        prefs = _prefs()
        if prefs is None or not prefs.folder:
            self.report({"ERROR"}, "Set the Fabrickator folder in the add-on preferences")
            return {"CANCELLED"}
        try:
            path = export_object(context.view_layer.objects.active, prefs.folder, prefs.mm_per_unit)
        except (OSError, ValueError) as err:
            self.report({"ERROR"}, str(err))
            return {"CANCELLED"}
        self.report({"INFO"}, f"Exported {path}")
        return {"FINISHED"}


class FABRICKATOR_PT_panel(bpy.types.Panel):
    bl_label = "Fabrickator"
    bl_space_type = "VIEW_3D"
    bl_region_type = "UI"
    bl_category = "Fabrickator"

    def draw(self, context):
        prefs = _prefs()
        if prefs is not None:
            self.layout.prop(prefs, "folder")
            self.layout.prop(prefs, "auto_export")
        self.layout.operator(FABRICKATOR_OT_export.bl_idname)


_CLASSES = (FabrickatorPreferences, FABRICKATOR_OT_export, FABRICKATOR_PT_panel)


def register():
    for cls in _CLASSES:
        bpy.utils.register_class(cls)
    if on_depsgraph_update not in bpy.app.handlers.depsgraph_update_post:
        bpy.app.handlers.depsgraph_update_post.append(on_depsgraph_update)


def unregister():
    if on_depsgraph_update in bpy.app.handlers.depsgraph_update_post:
        bpy.app.handlers.depsgraph_update_post.remove(on_depsgraph_update)
    for cls in reversed(_CLASSES):
        bpy.utils.unregister_class(cls)


if __name__ == "__main__":
    register()
