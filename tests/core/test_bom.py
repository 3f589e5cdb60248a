"""Tests of core.instructions.bom: bom.csv and the BrickLink wanted list add up to the layout."""

from __future__ import annotations

import csv
from collections import Counter
from pathlib import Path

import pytest
from lxml import etree

from core import pipeline
from core.catalog import BY_NUMBER
from core.errors import InputError
from core.instructions import bom, ldraw

from conftest import HMD_HIGH_RES

ROOT = Path(__file__).resolve().parents[2]
MODELS = ROOT.parent / "shared" / "models"


@pytest.fixture(scope="module")
def hmd(hmd_step):
    return pipeline.run(hmd_step, high_res=HMD_HIGH_RES, slice_parts=False)


def read_csv(path: Path) -> list[dict]:
    with open(path, newline="", encoding="utf-8") as f:
        return list(csv.DictReader(f))


@pytest.mark.slow
def test_csv_totals_match_the_layout(hmd, tmp_path):
    path = bom.write_csv(bom.lines(hmd.layout, hmd.printed), tmp_path / "bom.csv")
    rows = read_csv(path)
    assert list(rows[0]) == list(bom.COLUMNS)
    lego = [r for r in rows if r["kind"] == "lego"]
    want = Counter(b.part for b in hmd.layout.bricks if b.kind == "lego")
    assert {r["part"]: int(r["count"]) for r in lego} == dict(want)
    assert len({r["part"] for r in lego}) == len(lego)
    for r in lego:
        assert r["name"] == BY_NUMBER[r["part"]].name
        assert r["color"] == "Light Bluish Grey" and r["ldraw_color"] == "71" and r["bricklink_color"] == "86"
    printed = [r for r in rows if r["kind"] == "printed"]
    assert [r["part"] for r in printed] == [p.id for p in hmd.printed]
    for r, p in zip(printed, hmd.printed):
        assert float(r["volume_mm3"]) == pytest.approx(p.volume_mm3, abs=0.05)
        assert int(r["bricks_replaced"]) == len(p.bricks)
        assert float(r["print_s"]) > 60 and r["print_method"].startswith("estimate")
        assert r["file"].endswith(f"{p.id}.stl") and r["count"] == "1"
    assert sum(int(r["count"]) for r in rows) == sum(want.values()) + len(hmd.printed)


@pytest.mark.slow
def test_slicer_time_is_used_when_there(hmd):
    part = hmd.printed[0]
    old = part.print_s
    try:
        part.print_s = 1234.0
        row = next(r for r in bom.lines(hmd.layout, hmd.printed) if r.part == part.id)
        assert row.print_s == 1234.0 and row.print_method.startswith("slicer")
    finally:
        part.print_s = old


@pytest.mark.slow
def test_wanted_list_is_bricklink_xml_of_the_missing_bricks(hmd, tmp_path):
    path = bom.write_wanted_list(hmd.layout, tmp_path / "bricklink.xml", remarks="hmd & co")
    text = path.read_text(encoding="utf-8")
    assert text.startswith("<INVENTORY>")          # BrickLink refuses an XML declaration
    root = etree.fromstring(text.encode())
    items = root.findall("ITEM")
    want = Counter(b.part for b in hmd.layout.bricks if b.kind == "lego")
    got = {i.findtext("ITEMID"): int(i.findtext("MINQTY")) for i in items}
    assert got == dict(want)
    for i in items:
        assert i.findtext("ITEMTYPE") == "P"
        assert i.findtext("COLOR") == str(ldraw.COLORS[ldraw.LEGO_COLOR][1])
        assert i.findtext("REMARKS") == "hmd & co"
    other = next(p for p in want if p != "3001")
    owned = {"3001": 10_000, other: 1}
    got = {i.findtext("ITEMID"): int(i.findtext("MINQTY"))
           for i in etree.fromstring(bom.write_wanted_list(hmd.layout, tmp_path / "w.xml", owned)
                                     .read_bytes()).findall("ITEM")}
    assert "3001" not in got
    assert got.get(other, 0) == want[other] - 1


@pytest.mark.slow
def test_owned_counts_must_be_whole_numbers(hmd):
    for bad in (-1, 1.5, "3"):
        with pytest.raises(InputError, match="owned count"):
            bom.wanted(hmd.layout, {"3001": bad})


@pytest.mark.slow
def test_a_shared_model_without_printed_parts(tmp_path):
    path = MODELS / "xyz_calibration_cube.stl"
    if not path.is_file():
        pytest.skip(f"shared test models not found at {MODELS}")
    fab = pipeline.run(path)
    rows = read_csv(bom.write_csv(bom.lines(fab.layout, fab.printed), tmp_path / "bom.csv"))
    assert all(r["kind"] == "lego" for r in rows)
    assert sum(int(r["count"]) for r in rows) == len(fab.layout.bricks)


def test_props_need_the_most_of_each_part_standing_at_once():
    """A stands from step 3 until after step 10, B from 5 until after 8, C from 11 for
    good, D from 10 until after 12: at steps 5..8 A and B stand (3 bricks, 1 plate), at
    step 10 A and D (2 bricks); A's bricks serve C again.  By hand: 3 bricks, 1 plate."""
    props = [{"step": 3, "removed_after": 10, "parts": {"3005": 1}},
             {"step": 5, "removed_after": 8, "parts": {"3005": 2, "3024": 1}},
             {"step": 11, "removed_after": None, "parts": {"3005": 1}},
             {"step": 10, "removed_after": 12, "parts": {"3005": 1}}]
    assert bom.prop_counts(props) == {"3005": 3, "3024": 1}
    assert bom.prop_counts([]) == {}
