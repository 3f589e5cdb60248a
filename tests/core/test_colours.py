"""Tests of core.colours: one decision of a brick's colour that every output follows."""

from __future__ import annotations

import csv
import re

import numpy as np
import pytest
from PIL import Image

from core import colours, request
from core.errors import InputError
from core.instructions import bom, ldraw
from core.instructions.render import SHADE, render_layout
from core.model import CELL_MM, Brick, Grid, Layout


def layout_of(bricks, shape) -> Layout:
    """A Layout from (part, size, cell[, kind]) tuples; the grid is what they fill."""
    filled = np.zeros(shape, dtype=bool)
    out = []
    for n, (part, size, cell, *kind) in enumerate(bricks):
        brick = Brick(n, part, tuple(size), tuple(cell), kind=kind[0] if kind else "lego",
                      printed_part="P1" if kind and kind[0] == "printed" else None)
        filled[brick.slices()] = True
        out.append(brick)
    return Layout(Grid(np.zeros(3), np.array(CELL_MM), filled), out)


def wall() -> Layout:
    """Twelve 1x1 plates side by side and on top of each other, one of them printed."""
    bricks = [("3024", (1, 1, 1), (i, 0, k)) for i in range(4) for k in range(3)]
    bricks[5] = ("3024", (1, 1, 1), bricks[5][2], "printed")
    return layout_of(bricks, (4, 1, 3))


def test_bom_palette_draws_what_the_bom_orders():
    layout = wall()
    rgb = colours.brick_colours(layout, "bom")
    grey, orange = colours.rgb(colours.BOM_COLOR), colours.rgb(colours.PRINTED_COLOR)
    for b, c in zip(layout.bricks, rgb):
        assert tuple(c) == pytest.approx(orange if b.kind == "printed" else grey)
    rows = [r for r in bom.lines(layout) if r.kind == "lego"]
    assert [(r.ldraw_color, r.color, r.bricklink_color, r.count) for r in rows] == [
        (71, "Light Bluish Grey", 86, 11)]
    assert colours.rgb(rows[0].ldraw_color) == pytest.approx(tuple(rgb[0]))


def test_random_palette_is_a_display_aid_only(tmp_path):
    layout = wall()
    codes = colours.display_codes(layout, "random")
    lego = [c for b, c in zip(layout.bricks, codes) if b.kind == "lego"]
    assert set(lego) <= set(colours.RANDOM_CODES) and len(set(lego)) > 3
    assert codes[5] == colours.PRINTED_COLOR
    labels = layout.labels()
    for axis in range(3):
        a = np.moveaxis(labels, axis, 0)
        lo, hi = a[:-1].ravel(), a[1:].ravel()
        assert np.all(codes[lo] != codes[hi])
    assert np.array_equal(codes, colours.display_codes(layout, "random"))  # same every time
    # what is ordered and built stays in the BOM colour
    assert {r.ldraw_color for r in bom.lines(layout) if r.kind == "lego"} == {colours.BOM_COLOR}
    path = bom.write_wanted_list(layout, tmp_path / "w.xml")
    assert set(re.findall(r"<COLOR>(\d+)</COLOR>", path.read_text())) == {"86"}


def test_palettes_reach_the_picture(tmp_path):
    layout = wall()
    seen = {}
    for palette in colours.PALETTES:
        render_layout(layout, tmp_path / f"{palette}.png", size_px=(400, 300), palette=palette)
        with Image.open(tmp_path / f"{palette}.png") as im:
            px = np.asarray(im.convert("RGB"), dtype=np.int64).reshape(-1, 3)
        seen[palette] = px
    # the -y faces (the wall's front) of LEGO plates in the BOM grey, shaded as drawn
    grey = np.round(np.array(colours.rgb(colours.BOM_COLOR)) * SHADE[1] * 255)
    assert (np.abs(seen["bom"] - grey).max(axis=1) <= 1).sum() > 500
    assert (np.abs(seen["random"] - grey).max(axis=1) <= 1).sum() == 0
    for code in set(colours.display_codes(layout, "random").tolist()) - {colours.PRINTED_COLOR}:
        front = np.round(np.array(colours.rgb(code)) * SHADE[1] * 255)
        assert (np.abs(seen["random"] - front).max(axis=1) <= 1).sum() > 50, colours.name(code)


def test_ldraw_and_bom_agree_on_every_brick(tmp_path):
    layout = wall()
    steps = [[b.id for b in layout.bricks]]
    mesh = __import__("trimesh").creation.box(extents=(8, 8, 3.2))
    part = type("Part", (), {"id": "P1", "mesh": mesh})()
    path = ldraw.write(layout, [part], steps, tmp_path / "a.mpd")
    refs = [line.split() for line in path.read_text().splitlines() if line.startswith("1 ")]
    lego_refs = [r for r in refs if r[-1].endswith(".dat")]
    assert {int(r[1]) for r in lego_refs} == {colours.BOM_COLOR}
    assert [int(r[1]) for r in refs if r[-1].startswith("printed_")] == [colours.PRINTED_COLOR]
    out = tmp_path / "bom.csv"
    bom.write_csv(bom.lines(layout), out)
    with out.open() as f:
        row = next(r for r in csv.DictReader(f) if r["kind"] == "lego")
    assert int(row["ldraw_color"]) == colours.BOM_COLOR and int(row["count"]) == len(lego_refs)


def test_palette_is_a_checked_setting_with_a_cli_flag(tmp_path):
    assert request.DEFAULTS["palette"] == "bom"
    model = tmp_path / "m.stl"
    model.write_text("solid m\nendsolid m\n")
    assert request.request(str(model), palette="random").palette == "random"
    with pytest.raises(InputError, match="palette"):
        request.request(str(model), palette="rainbow")
    from core import cli

    args = cli._parser().parse_args(["fabricate", str(model), "--out", str(tmp_path / "o"),
                                     "--palette", "random"])
    assert args.palette == "random"


def test_colour_table_is_consistent():
    for code, (name, bl, bl_name, hex_rgb, rb) in colours.COLORS.items():
        assert re.fullmatch(r"#[0-9A-F]{6}", hex_rgb), code
        assert colours.name(code) == name and colours.bricklink_id(code) == bl
        assert colours.from_bricklink(bl) == code and colours.from_rebrickable(rb) == code
        assert colours.by_name(bl_name.upper()) == code == colours.by_name(name)
    assert len({v[1] for v in colours.COLORS.values()}) == len(colours.COLORS)
    assert len({v[4] for v in colours.COLORS.values()}) == len(colours.COLORS)
    assert colours.BOM_COLOR not in colours.RANDOM_CODES
    assert colours.PRINTED_COLOR not in colours.RANDOM_CODES
    # printed parts stand out from every brick colour
    for code in colours.RANDOM_CODES + (colours.BOM_COLOR,):
        assert colours.delta_e(colours.rgb(code), colours.rgb(colours.PRINTED_COLOR)) > 15, code


def test_inventory_colour_ids_from_design_notes():
    # DESIGN.md "The maker's workshop": Rebrickable ids equal LDraw codes for these, and
    # BrickLink numbers them 11 Black, 7 Blue, 5 Red, 3 Yellow, 1 White, 86 LBG, 85 DBG
    for ldraw, bricklink in ((0, 11), (1, 7), (4, 5), (14, 3), (15, 1), (71, 86), (72, 85)):
        assert colours.from_rebrickable(ldraw) == ldraw
        assert colours.from_bricklink(bricklink) == ldraw
    assert colours.by_name("light bluish gray") == 71
    with pytest.raises(InputError, match="colour"):
        colours.by_name("plaid")


def test_delta_e():
    assert colours.delta_e((1, 1, 1), (1, 1, 1)) == 0
    assert colours.delta_e((0, 0, 0), (1, 1, 1)) == pytest.approx(100, abs=0.1)
    assert colours.delta_e((1, 0, 0), (0, 1, 0)) > 100


def test_a_makers_own_colours_are_drawn_in_the_bom_palette():
    from core.model import Brick, Grid, Layout

    grid = Grid(filled=np.ones((4, 2, 6), dtype=bool), origin=(0.0, 0.0, 0.0), cell=(8.0, 8.0, 3.2))
    lay = Layout(grid, [Brick(0, "3001", (4, 2, 3), (0, 0, 0)), Brick(1, "3001", (4, 2, 3), (0, 0, 3))])
    assert colours.display_codes(lay, colouring={0: (0, True), 1: (71, False)}).tolist() == [0, 71]
    assert colours.display_codes(lay).tolist() == [71, 71]
    assert colours.brick_colours(lay, colouring={0: (15, True)})[0].tolist() == [1.0, 1.0, 1.0]
