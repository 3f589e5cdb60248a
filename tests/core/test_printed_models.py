"""Printed parts of models made of several solids or shells, end to end through the pipeline."""

import cadquery as cq
import pytest
import trimesh

from core import pipeline


def _parts_ok(out, report):
    assert report["printed_parts"], "a printed part was expected"
    for part in report["printed_parts"]:
        assert part["pieces"] == 1
        mesh = trimesh.load(out / "parts" / f"{part['id']}.stl")
        assert mesh.is_watertight and mesh.body_count == 1, part["id"]
        assert part["kept_mm3"] > 0


@pytest.mark.slow
def test_step_assembly_of_ten_solids_with_its_lower_30_percent_marked(tmp_path):
    # Ten 20 x 20 x 12 mm blocks in two rows, each overlapping its neighbour by 1 mm: one object.
    solids = [cq.Solid.makeBox(20, 20, 12, cq.Vector(19 * (n % 5), 19 * (n // 5), 0)) for n in range(10)]
    step = tmp_path / "assembly.step"
    cq.exporters.export(cq.Workplane().add(cq.Compound.makeCompound(solids)), str(step))
    out = tmp_path / "out"
    report = pipeline.fabricate(step, out, picture=False, slice_parts=False,
                                high_res=["-1,-1,-1,97,40,3.6"])
    _parts_ok(out, report)
    union = cq.Workplane().add(solids[0]).union(cq.Workplane().add(solids[1:])).val().Volume()
    assert sum(p["kept_mm3"] for p in report["printed_parts"]) < union


@pytest.mark.slow
def test_mesh_of_five_watertight_shells_with_one_end_marked(tmp_path):
    shells = [trimesh.creation.box(bounds=[[15 * n, 0, 0], [15 * n + 20, 20, 16]]) for n in range(5)]
    mesh = trimesh.util.concatenate(shells)
    assert mesh.body_count == 5
    stl = tmp_path / "shells.stl"
    mesh.export(stl)
    out = tmp_path / "out"
    report = pipeline.fabricate(stl, out, picture=False, slice_parts=False,
                                high_res=["-1,-1,-1,20,21,17"])
    _parts_ok(out, report)
    # The model's union inside the marked cells is kept, less the sockets (none: nothing is below).
    part = report["printed_parts"][0]
    assert part["engaged"]["sockets"] == 0


@pytest.mark.slow
def test_split_and_merge_never_leave_a_part_of_several_solids(tmp_path):
    # A block whose top face cuts the top plate layer: splitting that layer off a part leaves
    # each part one solid.
    block = cq.Workplane("XY").box(48, 16, 20.0, centered=(True, True, False))
    step = tmp_path / "block.step"
    cq.exporters.export(block, str(step))
    region = "-25,-9,-1,25,9,21"
    whole = pipeline.run(step, high_res=[region], slice_parts=False)
    ids = [b.id for b in whole.layout.bricks if b.kind == "printed"]
    top = max(b.cell[2] + b.size[2] for b in whole.layout.bricks)
    top_ids = [b.id for b in whole.layout.bricks if b.kind == "printed" and b.cell[2] + b.size[2] == top]
    split = pipeline.run(step, high_res=[region], slice_parts=False,
                         part_edits=[{"op": "split", "bricks": top_ids}])
    merged = pipeline.run(step, high_res=[region], slice_parts=False,
                          part_edits=[{"op": "split", "bricks": ids}, {"op": "merge", "bricks": ids}])
    for fab in (whole, split, merged):
        for part in fab.printed:
            assert part.mesh.body_count == 1 and part.mesh.is_watertight
    assert len(split.printed) == 1 + len(top_ids)
    assert len(merged.printed) == 1
    # Parts split from each other clamp: the lower part carries studs under the top pieces.
    lower = max(split.printed, key=lambda p: len(p.bricks))
    assert lower.engaged["studs"] > 0
