"""Tests of core.instructions: drawing order, the self-contained page and write_assembly."""

from __future__ import annotations

import csv
import json
import re
from pathlib import Path

import numpy as np
import pytest

from core import build_order, instructions, layout as layout_stage, ldraw, pipeline
from core.errors import InputError
from core.model import Grid

from conftest import HMD_HIGH_RES

ROOT = Path(__file__).resolve().parents[2]
VIEW = np.array([1.0, 1.0, -1.0])


@pytest.fixture(scope="module")
def hmd(tmp_path_factory, hmd_step):
    fab = pipeline.run(hmd_step, high_res=HMD_HIGH_RES, slice_parts=False)
    out = tmp_path_factory.mktemp("assembly")
    result = instructions.write_assembly(fab.layout, fab.printed, out, title="hmd.step <test>")
    return fab, out, result


def occlusion(boxes: np.ndarray) -> np.ndarray:
    """(n, n) bool: box i hides part of box j (a view ray meets the inside of i, then of j).

    Independent of the module: a ray along VIEW from a point of i reaches a
    point of j exactly when the open box j - i (Minkowski difference) meets
    the open half-line t * VIEW, t > 0 (slab test).
    """
    lo = boxes[None, :, 0] - boxes[:, None, 1]
    hi = boxes[None, :, 1] - boxes[:, None, 0]
    ta, tb = lo / VIEW, hi / VIEW
    t0 = np.maximum(np.minimum(ta, tb).max(axis=2), 0.0)
    t1 = np.maximum(ta, tb).min(axis=2)
    hit = t0 < t1 - 1e-9
    np.fill_diagonal(hit, False)
    return hit


def assert_valid_order(boxes, order):
    position = np.empty(len(order), dtype=np.int64)
    position[order] = np.arange(len(order))
    hides = occlusion(boxes)
    front, back = np.nonzero(hides)
    assert np.all(position[front] > position[back]), "a box is drawn before a box it hides"


def assert_pieces_cover_bricks(layout, pieces, owner):
    boxes = instructions.brick_boxes(layout)
    volume = np.prod(pieces[:, 1] - pieces[:, 0], axis=1)
    assert np.allclose(np.bincount(owner, weights=volume, minlength=len(boxes)),
                       np.prod(boxes[:, 1] - boxes[:, 0], axis=1))
    assert np.all(pieces[:, 0] >= boxes[owner, 0] - 1e-9) and np.all(pieces[:, 1] <= boxes[owner, 1] + 1e-9)


def test_drawing_order_is_valid_on_the_real_model(hmd):
    fab, _, result = hmd
    pieces, owner, order, split = instructions.drawing_pieces(fab.layout)
    assert sorted(order.tolist()) == list(range(len(pieces)))
    assert split == result["split_bricks"]
    assert_pieces_cover_bricks(fab.layout, pieces, owner)
    assert_valid_order(pieces, order)
    with pytest.raises(AssertionError):
        assert_valid_order(pieces, order[::-1])


def test_bricks_on_occlusion_cycles_are_split_into_columns():
    # a staggered hollow box: its bricks hide each other in cycles
    filled = np.ones((40, 40, 30), dtype=bool)
    filled[3:-3, 3:-3, 3:] = False
    lay = layout_stage.lay_out(Grid(np.zeros(3), np.array([8.0, 8.0, 3.2]), filled), seed=0)
    boxes = instructions.brick_boxes(lay)
    _, cycles = instructions.painter_order(boxes)
    assert cycles > 0
    pieces, owner, order, split = instructions.drawing_pieces(lay)
    assert split > 0 and len(pieces) > len(boxes)
    columns = np.bincount(owner) > 1
    assert np.allclose(pieces[columns[owner], 1, :2] - pieces[columns[owner], 0, :2], [8.0, 8.0])
    assert_pieces_cover_bricks(lay, pieces, owner)
    assert_valid_order(pieces, order)


def test_an_occlusion_cycle_is_broken_and_counted():
    boxes = np.array([[[2.0, 1, 2], [5, 5, 7]], [[5.0, 0, 3], [6, 3, 7]], [[4.0, 0, 2], [7, 1, 3]]])
    hides = occlusion(boxes)
    assert hides[0, 1] and hides[1, 2] and hides[2, 0]   # a real cycle
    order, cycles = instructions.painter_order(boxes)
    assert sorted(order.tolist()) == [0, 1, 2] and cycles == 1


def test_page_is_self_contained(hmd):
    _, out, _ = hmd
    text = (out / "instructions.html").read_text(encoding="utf-8")
    assert text.startswith("<!DOCTYPE html>")
    urls = re.findall(r"(?:https?:)?//[\w.-]+", text)
    assert set(urls) <= {"http://www.w3.org"}, urls       # only the SVG namespace name
    assert not re.search(r"<(?:script|img|link|iframe)[^>]+(?:src|href)=", text)
    assert "@import" not in text and "url(http" not in text
    assert "hmd.step &lt;test&gt;" in text and "<test>" not in text


def test_page_draws_every_brick_with_its_step(hmd):
    fab, out, result = hmd
    text = (out / "instructions.html").read_text(encoding="utf-8")
    groups = re.findall(r'<g class="b( pp)? (done|now|todo)" data-s="(\d+)" data-id="(\d+)">', text)
    pieces, owner, _, _ = instructions.drawing_pieces(fab.layout)
    assert len(groups) == len(pieces)
    step = {b.id: b.step for b in fab.layout.bricks}
    assert {(int(i), int(s)) for _, _, s, i in groups} == set(step.items())
    printed = {b.id for b in fab.layout.bricks if b.kind == "printed"}
    assert {int(i) for pp, _, _, i in groups if pp} == printed
    # the page opens on step 1: its bricks blue, later ones hidden
    assert all((st == "now") == (s == "1") and (st == "todo") == (s != "1") for _, st, s, _ in groups)
    for p in fab.printed:
        assert re.search(rf'<text class="lbl [a-z]+" data-s="\d+"[^>]*>{p.id}</text>', text)
    data = json.loads(re.search(r'<script id="data" type="application/json">(.*?)</script>', text, re.S)
                      .group(1))
    assert len(data["steps"]) == result["steps"]
    assert [s["n"] for s in data["steps"]] == list(range(1, result["steps"] + 1))
    assert sum(s["nb"] for s in data["steps"]) == len(fab.layout.bricks)
    assert {s["p"] for s in data["steps"] if s["p"]} == {p.id for p in fab.printed}
    for s in data["steps"]:
        assert s["p"] or sum(c[2] for c in s["c"]) == s["nb"]
    for number in {b.part for b in fab.layout.bricks if b.kind == "lego"}:
        assert f'<symbol id="i{number}"' in text


def test_write_assembly_sets_steps_and_writes_all_files(hmd):
    fab, out, result = hmd
    assert sorted(p.name for p in out.iterdir()) == sorted(result["files"].values())
    assert all(b.step is not None for b in fab.layout.bricks)
    assert result["steps"] == max(b.step for b in fab.layout.bricks)
    lego = sum(1 for b in fab.layout.bricks if b.kind == "lego")
    assert result["assembly_s"] == pytest.approx(10.0 * lego + 30.0 * len(fab.printed))
    assert result["unattached_bricks"] == [] and result["early_parts"] == []
    assert result["split_bricks"] >= 0
    doc = ldraw.parse(out / "assembly.mpd")
    assert len(doc.main.steps) == result["steps"]
    with open(out / "bom.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    assert sum(int(r["count"]) for r in rows if r["kind"] == "lego") == lego
    json.dumps(result)


def test_write_assembly_refuses_a_missing_folder_and_bad_numbers(hmd, tmp_path):
    fab, _, _ = hmd
    with pytest.raises(FileNotFoundError, match="does not exist"):
        instructions.write_assembly(fab.layout, fab.printed, tmp_path / "nope")
    with pytest.raises(InputError, match="seconds"):
        instructions.write_assembly(fab.layout, fab.printed, tmp_path, seconds_per_brick=-5)
    with pytest.raises(ValueError, match="per step"):
        instructions.write_assembly(fab.layout, fab.printed, tmp_path, bricks_per_step=0)


def test_page_refuses_an_order_that_misses_bricks(hmd):
    fab, _, _ = hmd
    order = build_order.plan(fab.layout)
    short = build_order.BuildOrder(order.steps[:-1])
    with pytest.raises(ValueError, match="no assembly step"):
        instructions.page(fab.layout, short)


def test_screen_projection_matches_the_view():
    # moving along the view direction does not move the picture
    p = np.array([[3.0, -2.0, 5.0]])
    assert np.allclose(instructions.screen(p), instructions.screen(p + 2.5 * VIEW))
    # up in the model is up in the picture (SVG y grows downwards)
    assert instructions.screen(np.array([0, 0, 1.0]))[1] < 0
