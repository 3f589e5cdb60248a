"""Tests of core.instructions.page: drawing order, the self-contained page and write_assembly."""

from __future__ import annotations

import csv
import json
import re
from pathlib import Path

import numpy as np
import trimesh
import pytest

from core import pipeline
from core.errors import InputError
from core.instructions import build_order, drawing_order, ldraw, page as instructions, picture
from core.layout import greedy as layout_stage
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


@pytest.mark.slow
def test_the_printed_parts_the_steps_name_carry_their_engraved_ids(hmd):
    """The steps tell the builder to find each printed part's ID engraved on its side: both
    lens mounts of the demo have it, on a side whose slab in front is free of the part (its
    middle may be covered by the part's own cells: then the ID moves along the side)."""
    fab, _, _ = hmd
    assert [p.id for p in fab.printed] == ["P1", "P2"]
    for part in fab.printed:
        assert part.engraved, part.engraving
        where = part.engraving
        normal, centre = np.array(where["normal"]), np.array(where["centre_mm"])
        width, height = where["text_mm"]
        half = np.abs(np.cross([0.0, 0.0, 1.0], normal)) * width / 2 + np.array([0, 0, height / 2])
        lo, hi = np.sort(np.stack([centre - half + normal * 0.05, centre + half + normal * 1.0]), axis=0)
        points = lo + (hi - lo) * np.random.default_rng(1).random((400, 3))
        assert not part.mesh.contains(points).any()
        inner = centre - normal * 0.7
        assert part.mesh.contains(inner[None])[0], "no wall behind the ID"


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
    boxes = drawing_order.brick_boxes(layout)
    volume = np.prod(pieces[:, 1] - pieces[:, 0], axis=1)
    assert np.allclose(np.bincount(owner, weights=volume, minlength=len(boxes)),
                       np.prod(boxes[:, 1] - boxes[:, 0], axis=1))
    assert np.all(pieces[:, 0] >= boxes[owner, 0] - 1e-9) and np.all(pieces[:, 1] <= boxes[owner, 1] + 1e-9)


@pytest.mark.slow
def test_drawing_order_is_valid_on_the_real_model(hmd):
    fab, _, result = hmd
    pieces, owner, order, split = drawing_order.drawing_pieces(fab.layout)
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
    boxes = drawing_order.brick_boxes(lay)
    _, cycles = drawing_order.painter_order(boxes)
    assert cycles > 0
    pieces, owner, order, split = drawing_order.drawing_pieces(lay)
    assert split > 0 and len(pieces) > len(boxes)
    columns = np.bincount(owner) > 1
    assert np.allclose(pieces[columns[owner], 1, :2] - pieces[columns[owner], 0, :2], [8.0, 8.0])
    assert_pieces_cover_bricks(lay, pieces, owner)
    assert_valid_order(pieces, order)


def test_an_occlusion_cycle_is_broken_and_counted():
    boxes = np.array([[[2.0, 1, 2], [5, 5, 7]], [[5.0, 0, 3], [6, 3, 7]], [[4.0, 0, 2], [7, 1, 3]]])
    hides = occlusion(boxes)
    assert hides[0, 1] and hides[1, 2] and hides[2, 0]   # a real cycle
    order, cycles = drawing_order.painter_order(boxes)
    assert sorted(order.tolist()) == [0, 1, 2] and cycles == 1


@pytest.mark.slow
def test_page_is_self_contained(hmd):
    _, out, _ = hmd
    text = (out / "instructions.html").read_text(encoding="utf-8")
    assert text.startswith("<!DOCTYPE html>")
    urls = re.findall(r"(?:https?:)?//[\w.-]+", text)
    assert set(urls) <= {"http://www.w3.org"}, urls       # only the SVG namespace name
    assert not re.search(r"<(?:script|img|link|iframe)[^>]+(?:src|href)=", text)
    assert "@import" not in text and "url(http" not in text
    assert "hmd.step &lt;test&gt;" in text and "<test>" not in text


@pytest.mark.slow
def test_page_draws_every_brick_with_its_step(hmd):
    fab, out, result = hmd
    text = (out / "instructions.html").read_text(encoding="utf-8")
    groups = re.findall(r'<g class="b( pp)? (done|now|todo)" data-s="(\d+)" data-id="(\d+)">', text)
    pieces, owner, _, _ = drawing_order.drawing_pieces(fab.layout)
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
    engraved = {p.id: p.engraved for p in fab.printed}
    assert all(s["pe"] is engraved[s["p"]] for s in data["steps"] if s["p"])
    for s in data["steps"]:
        assert s["p"] or sum(c[2] for c in s["c"]) == s["nb"]
    for number in {b.part for b in fab.layout.bricks if b.kind == "lego"}:
        assert f'<symbol id="i{number}"' in text


@pytest.mark.slow
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


@pytest.mark.slow
def test_write_assembly_refuses_a_missing_folder_and_bad_numbers(hmd, tmp_path):
    fab, _, _ = hmd
    with pytest.raises(FileNotFoundError, match="does not exist"):
        instructions.write_assembly(fab.layout, fab.printed, tmp_path / "nope")
    with pytest.raises(InputError, match="seconds"):
        instructions.write_assembly(fab.layout, fab.printed, tmp_path, seconds_per_brick=-5)
    with pytest.raises(ValueError, match="per step"):
        instructions.write_assembly(fab.layout, fab.printed, tmp_path, bricks_per_step=0)


@pytest.mark.slow
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


def test_split_triangles_keeps_area_and_winding():
    tri = np.array([[[0.0, 0, 0], [4, 0, 0], [0, 4, 1]], [[0.0, 0, 5], [1, 0, 5], [0, 1, 5]]])
    shade = np.array([3, 7])
    out, keep = picture.split_triangles(tri, 0, 1.5, shade)
    area = lambda t: np.linalg.norm(np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0]), axis=1) / 2
    normal = lambda t: np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0])
    assert len(out) == 4                                 # the first crosses x = 1.5, the second not
    assert area(out).sum() == pytest.approx(area(tri).sum())
    crossing = keep == 3
    assert np.all(normal(out[crossing]) @ normal(tri[:1])[0] > 0)   # same winding as the original
    for t in out[crossing]:                              # each piece lies on one side of the plane
        assert np.all(t[:, 0] <= 1.5 + 1e-9) or np.all(t[:, 0] >= 1.5 - 1e-9)


def _areas(path: str) -> list[float]:
    """Signed shoelace areas of the closed sub-paths of absolute M/L path data."""
    out = []
    for sub in re.findall(r"M([^z]*)z", path):
        pts = np.array([[float(v) for v in re.findall(r"-?[\d.]+", p)] for p in sub.split("L")])
        x, y = pts[:, 0], pts[:, 1]
        out.append(0.5 * float(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1))))
    return out


def test_outline_of_a_ring_seen_along_its_axis_has_its_hole():

    ring = trimesh.creation.annulus(r_min=6.0, r_max=10.0, height=3.0, sections=96)
    ring.apply_transform(trimesh.geometry.align_vectors([0, 0, 1], -VIEW / np.linalg.norm(VIEW)))
    areas = sorted(abs(a) for a in _areas(picture.outline(ring, origin=np.zeros(3))))
    assert len(areas) == 2                               # the rim and the hole
    assert areas[1] == pytest.approx(np.pi * 10.0 ** 2, rel=0.03)
    assert areas[0] == pytest.approx(np.pi * 6.0 ** 2, rel=0.03)


@pytest.mark.slow
def test_printed_parts_are_drawn_from_their_meshes(hmd):
    fab, out, _ = hmd
    text = (out / "instructions.html").read_text(encoding="utf-8")
    _, facts = instructions.svg_picture(fab.layout, build_order.plan(fab.layout), printed_parts=fab.printed)
    assert facts["meshed_parts"] == sorted(p.id for p in fab.printed)
    groups = dict(re.findall(r'<g class="b pp [a-z]+" data-s="\d+" data-id="(\d+)">(.*?)</g>', text))
    assert set(groups) == {str(b) for p in fab.printed for b in p.bricks}
    assert all(not re.search(r'class="[lft]"', body) for body in groups.values())   # no box faces
    assert sum(bool(re.search(r'class="m\d"', body)) for body in groups.values()) > len(groups) / 2
    for p in fab.printed:                                # one outline per part, at the part's step
        step = next(b.step for b in fab.layout.bricks if b.id == p.bricks[0])
        assert re.search(rf'<path class="ol [a-z]+" data-s="{step}" data-part="{p.id}" d="M', text)


@pytest.mark.slow
def test_inserted_part_is_highlighted_with_its_hole_showing(hmd, tmp_path):
    """The step that inserts the lens mount P1, as Chromium shows it: where the part's
    own surface is in front, the pixels carry the inserted part's colours; through the
    lens bore they do not, where a block would have covered it."""
    webdriver = pytest.importorskip("selenium.webdriver", reason="selenium is not installed")
    if not (Path("/usr/bin/chromium").exists() and Path("/usr/bin/chromedriver").exists()):
        pytest.skip("chromium and chromedriver are not installed (apt-get install chromium chromium-driver)")
    import io

    from PIL import Image
    from selenium.webdriver.chrome.service import Service

    fab, out, _ = hmd
    part = next(p for p in fab.printed if p.mesh.bounds[0][0] < 0)      # the left lens mount
    step = next(b.step for b in fab.layout.bricks if b.id == part.bricks[0])
    options = webdriver.ChromeOptions()
    options.binary_location = "/usr/bin/chromium"
    for arg in ("--headless=new", "--no-sandbox", "--disable-gpu", "--window-size=1600,1200",
                f"--user-data-dir={tmp_path / 'profile'}", "--force-device-scale-factor=1"):
        options.add_argument(arg)
    driver = webdriver.Chrome(service=Service("/usr/bin/chromedriver"), options=options)
    try:
        driver.get((out / "instructions.html").as_uri() + f"#{step}")
        assert driver.execute_script("return window.fabrickator.current()") == step
        ctm = driver.execute_script("const m = document.getElementById('model').getScreenCTM();"
                                    "return [m.a, m.b, m.c, m.d, m.e, m.f];")
        shown = driver.execute_script(
            "return Array.from(document.querySelectorAll('#outlines path'))"
            ".filter(p => getComputedStyle(p).display !== 'none').map(p => p.dataset.part)")
        image = np.asarray(Image.open(io.BytesIO(driver.get_screenshot_as_png())).convert("RGB"), float)
    finally:
        driver.quit()
    assert shown == [part.id]                            # only the inserted part's outline is drawn

    def pixel(points_mm):
        xy = instructions.screen(np.asarray(points_mm, float) - fab.layout.grid.origin)
        a, b, c, d, e, f = ctm
        px = np.rint(np.stack([a * xy[:, 0] + c * xy[:, 1] + e, b * xy[:, 0] + d * xy[:, 1] + f], 1))
        return image[px[:, 1].astype(int), px[:, 0].astype(int)]

    hexes = lambda colours: np.array([[int(h[i:i + 2], 16) for i in (1, 3, 5)] for h in colours], float)
    now = hexes(picture.shade_colours(*instructions.PRINTED))
    done = hexes(picture.shade_colours(*instructions.PRINTED_DONE))
    near = lambda rgb, palette: np.min(np.linalg.norm(rgb[:, None] - palette[None], axis=2), axis=1)

    # view rays through a lattice of points on the part's front: first hits on the part
    lo, hi = part.mesh.bounds
    u, w = np.meshgrid(np.linspace(lo[0] + 2, hi[0] - 2, 40), np.linspace(lo[2] + 2, hi[2] - 2, 40))
    targets = np.column_stack([u.ravel(), np.full(u.size, lo[1]), w.ravel()])
    view = VIEW / np.linalg.norm(VIEW)
    origins = targets - 200.0 * view
    rays = trimesh.ray.ray_triangle.RayMeshIntersector(part.mesh)
    hit = rays.intersects_any(origins, np.tile(view, (len(origins), 1)))
    plo, phi = fab.layout.boxes_mm()
    built = np.array([b.step < step for b in fab.layout.bricks])
    blo, bhi = plo[built], phi[built]

    def blocked(points):
        """Does a brick built before the step lie on the view ray in front of each point?"""
        t0 = (blo[None] - points[:, None]) / -view
        t1 = (bhi[None] - points[:, None]) / -view
        near_t = np.minimum(t0, t1).max(axis=2)
        far_t = np.maximum(t0, t1).min(axis=2)
        return ((near_t < far_t) & (far_t > 0)).any(axis=1)

    locations, index, _ = rays.intersects_location(origins[hit], np.tile(view, (hit.sum(), 1)),
                                                   multiple_hits=False)
    first = np.full((hit.sum(), 3), np.nan)
    first[index] = locations
    on_part = first[~np.isnan(first[:, 0])]
    on_part = on_part[~blocked(on_part - 0.5 * view)]
    assert len(on_part) > 50
    colours = pixel(on_part)
    assert np.mean(near(colours, now) < 30) > 0.75       # the inserted part's bright shades (else edges)
    assert np.mean(near(colours, done) < near(colours, now)) < 0.1

    # the lens bore: rays through it miss the part although they pass inside its bricks
    members = [n for n, b in enumerate(fab.layout.bricks) if b.id in part.bricks]
    inside = np.zeros(len(targets), bool)
    for n in members:
        inside |= np.all((targets >= plo[n]) & (targets <= phi[n]), axis=1)
    hole = targets[~hit & inside]
    hole = hole[~blocked(hole)]
    assert len(hole) > 20                                # a block would cover all of these
    assert np.mean(near(pixel(hole), now) > 60) > 0.9
