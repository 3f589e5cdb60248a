"""The catalog of plates and bricks and the user's restriction of it."""

import pytest

from core import catalog
from core.errors import InputError


def test_catalog_has_every_footprint_as_plate_and_brick():
    assert len(catalog.CATALOG) == 22
    footprints = {p.footprint for p in catalog.CATALOG}
    assert footprints == {(1, 1), (1, 2), (1, 3), (1, 4), (1, 6), (1, 8),
                          (2, 2), (2, 3), (2, 4), (2, 6), (2, 8)}
    assert catalog.BY_NUMBER["3001"].footprint == (2, 4)
    assert catalog.BY_NUMBER["3001"].layers == 3
    assert catalog.BY_NUMBER["3024"].layers == 1
    assert catalog.BY_NUMBER["2456"].name == "Brick 2 x 6"
    assert catalog.BY_NUMBER["3001"].orientations() == ((2, 4), (4, 2))
    assert catalog.BY_NUMBER["3003"].orientations() == ((2, 2),)


@pytest.mark.parametrize("spec, expected", [
    (None, 22), ("", 22), ("all", 22), ("plates", 11),
    ("3024,3001", 2), ("3024, brick2x4, plate4x2", 3), ("bricks,3024", 12),
])
def test_select(spec, expected):
    assert len(catalog.select(spec)) == expected


@pytest.mark.parametrize("spec, word", [("bricks", "3024"), ("3024,9999", "9999"),
                                        ("3024,plate3x3", "plate3x3")])
def test_select_refuses(spec, word):
    with pytest.raises(InputError, match=word):
        catalog.select(spec)
