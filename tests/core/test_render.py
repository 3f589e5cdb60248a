"""Tests of core.instructions.render: a real PNG of the asked size, occlusion, colours."""

from __future__ import annotations

import numpy as np
import pytest
from PIL import Image

from core.instructions.render import PRINTED_RGB, SHADE, brick_colours, render_layout
from core.model import CELL_MM, Brick, Grid, Layout


def layout_of(bricks: list[tuple], shape) -> Layout:
    """A Layout from (part, size, cell[, kind]) tuples; the grid is what they fill."""
    filled = np.zeros(shape, dtype=bool)
    out = []
    for n, (part, size, cell, *kind) in enumerate(bricks):
        brick = Brick(n, part, tuple(size), tuple(cell), kind=kind[0] if kind else "lego",
                      printed_part="P1" if kind and kind[0] == "printed" else None)
        assert not filled[brick.slices()].any()
        filled[brick.slices()] = True
        out.append(brick)
    return Layout(Grid(np.zeros(3), np.array(CELL_MM), filled), out)


def staircase() -> Layout:
    bricks = [("3001", (2, 4, 3), (i, j, 0)) for i in (0, 2, 4) for j in (0, 4)]
    bricks += [("3001", (4, 2, 3), (0, 0, 3)), ("3020", (2, 4, 1), (0, 0, 6)),
               ("3005", (1, 1, 3), (4, 0, 3), "printed")]
    return layout_of(bricks, (6, 8, 9))


def pixels(path) -> np.ndarray:
    with Image.open(path) as im:
        assert im.format == "PNG"
        return np.asarray(im.convert("RGB"), dtype=np.int64)


def printed_pixels(img: np.ndarray) -> int:
    """Pixels of the colour of a printed brick's top face (to one level)."""
    top = (PRINTED_RGB * SHADE[2] * 255).round()
    return int((np.abs(img - top).max(axis=-1) <= 1).sum())


def test_renders_png_of_requested_size(tmp_path):
    path = tmp_path / "layout.png"
    render_layout(staircase(), path, size_px=(640, 480), title="staircase")
    img = pixels(path)
    assert img.shape == (480, 640, 3)
    assert img.std() > 20
    assert (img.sum(axis=-1) < 600).mean() > 0.1     # a good part is not white


def test_a_second_picture_from_the_cache_is_the_picture_drawn_afresh(tmp_path):
    """The stress picture reuses the layout picture's polygons (``cache``): pixel for pixel
    the picture drawn without it, in its own colours."""
    layout = staircase()
    red = np.tile([0.9, 0.1, 0.1], (len(layout.bricks), 1))
    cache: dict = {}
    render_layout(layout, tmp_path / "a.png", size_px=(640, 480), title="layout", cache=cache)
    render_layout(layout, tmp_path / "b.png", size_px=(640, 480), title="stress", colours=red,
                  cache=cache)
    assert len(cache) == 1
    render_layout(layout, tmp_path / "c.png", size_px=(640, 480), title="stress", colours=red)
    assert np.array_equal(pixels(tmp_path / "b.png"), pixels(tmp_path / "c.png"))
    assert not np.array_equal(pixels(tmp_path / "a.png"), pixels(tmp_path / "b.png"))


@pytest.mark.parametrize("size", [(333, 257), (100, 300)])
def test_odd_sizes(tmp_path, size):
    render_layout(staircase(), tmp_path / "a.png", size_px=size)
    assert pixels(tmp_path / "a.png").shape == (size[1], size[0], 3)


def test_empty_layout_gives_a_picture_that_says_so(tmp_path):
    empty = Layout(Grid(np.zeros(3), np.array(CELL_MM), np.zeros((2, 2, 2), dtype=bool)), [])
    render_layout(empty, tmp_path / "e.png", size_px=(300, 200))
    img = pixels(tmp_path / "e.png")
    assert img.shape == (200, 300, 3)
    assert img.std() > 0                             # the message


def test_printed_bricks_are_grey_and_hidden_ones_are_not_drawn_over(tmp_path):
    # A printed 1x1 plate behind an L-shaped wall two bricks high, seen from
    # (-x, -y, +z): every view ray from it meets the wall first.
    wall = [("3005", (1, 1, 3), (0, j, k)) for j in (0, 1) for k in (0, 3)]
    wall += [("3005", (1, 1, 3), (1, 0, k)) for k in (0, 3)]
    hidden = layout_of(wall + [("3024", (1, 1, 1), (1, 1, 0), "printed")], (2, 2, 6))
    render_layout(hidden, tmp_path / "h.png", size_px=(400, 400))
    assert printed_pixels(pixels(tmp_path / "h.png")) == 0
    low_wall = [b for b in wall if b[2][2] == 0]
    shown = layout_of(low_wall + [("3024", (1, 1, 1), (1, 1, 0), "printed")], (2, 2, 3))
    render_layout(shown, tmp_path / "s.png", size_px=(400, 400))
    assert printed_pixels(pixels(tmp_path / "s.png")) > 100


def test_neighbouring_bricks_get_different_colours():
    rng = np.random.default_rng(3)
    bricks = [("3024", (1, 1, 1), (i, j, k)) for i in range(5) for j in range(4) for k in range(3)]
    order = rng.permutation(len(bricks))
    layout = layout_of([bricks[n] for n in order], (5, 4, 3))
    rgb = brick_colours(layout, layout.labels(), palette="random")
    lab = layout.labels()
    for axis in range(3):
        a, b = np.moveaxis(lab, axis, 0)[:-1], np.moveaxis(lab, axis, 0)[1:]
        assert np.all(np.any(rgb[a.ravel()] != rgb[b.ravel()], axis=-1))


def test_many_bricks(tmp_path):
    bricks = [("3024", (1, 1, 1), (i, j, k)) for i in range(20) for j in range(20) for k in range(9)
              if (i + j + k) % 3]
    render_layout(layout_of(bricks, (20, 20, 9)), tmp_path / "m.png", size_px=(800, 600))
    assert pixels(tmp_path / "m.png").std() > 20


def test_bad_arguments(tmp_path):
    with pytest.raises(ValueError):
        render_layout(staircase(), tmp_path / "a.png", size_px=(0, 100))
    with pytest.raises(ValueError):
        render_layout(staircase(), tmp_path / "a.png", size_px="big")
    with pytest.raises(FileNotFoundError):
        render_layout(staircase(), tmp_path / "missing" / "a.png")


@pytest.mark.parametrize("size", [(1200, 900), (400, 300)])
def test_a_long_title_is_broken_into_lines_that_stay_inside_the_picture(tmp_path, size):
    """The stress picture's title of a failing bunny (119 characters) is wider than the
    picture on one line: it goes on more lines, each inside the picture.  Drawn over no
    bricks (the words "no bricks" are grey), every dark pixel is the title's."""
    title = ("stanford_bunny_open.obj on a baseplate, 554 g: 21 brick(s) fail, worst utilisation 2.41 "
             "(dark 0, red 1, white failing)")
    render_layout(layout_of([], (2, 2, 2)), tmp_path / "a.png", size_px=size, title=title)
    dark = pixels(tmp_path / "a.png").sum(axis=-1) < 300
    rows, cols = np.flatnonzero(dark.any(axis=1)), np.flatnonzero(dark.any(axis=0))
    assert cols.min() > 2 and cols.max() < size[0] - 3   # not cut at either side
    assert rows.max() < 0.2 * size[1]                    # above the picture
    assert (np.diff(rows) > 1).sum() >= 1                # more than one line of text
