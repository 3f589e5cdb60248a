"""The inventory reader against files written by hand in the three formats makers export."""

from __future__ import annotations

import pytest

from core import inventory
from core.errors import InputError

# The same box in three formats: 6 Light Bluish Grey 2x4 bricks (3001), 10 Red 2x2 bricks
# (3003), 4 Black 1x2 plates (3023), 2 White 2x2 plates (3022), a Red 2x2 slope (3039,
# not a catalog part) and one Light Bluish Grey 2x4 brick more in a second row.
REBRICKABLE = """Part,Color,Quantity
3001,71,6
3003,4,10
3023,0,4
3022,15,2
3039,4,3
3001,71,1
"""

SET_CSV = """Set Number,Part,Color,Quantity,Is Spare
10696-1,3001,71,6,False
10696-1,3003,4,10,False
10696-1,3023,0,4,False
10696-1,3022,15,1,False
10696-1,3022,15,1,True
10696-1,3039,4,3,False
10696-1,3001,71,1,False
"""

BRICKLINK = """<INVENTORY>
  <ITEM><ITEMTYPE>P</ITEMTYPE><ITEMID>3001</ITEMID><COLOR>86</COLOR><MINQTY>7</MINQTY></ITEM>
  <ITEM>
    <ITEMTYPE>P</ITEMTYPE><ITEMID>3003</ITEMID><COLOR>5</COLOR><QTY>10</QTY>
  </ITEM>
  <ITEM><ITEMTYPE>P</ITEMTYPE><ITEMID>3023</ITEMID><COLOR>11</COLOR><MINQTY>4</MINQTY></ITEM>
  <ITEM><ITEMTYPE>P</ITEMTYPE><ITEMID>3022</ITEMID><COLOR>1</COLOR><MINQTY>2</MINQTY></ITEM>
  <ITEM><ITEMTYPE>P</ITEMTYPE><ITEMID>3039</ITEMID><COLOR>5</COLOR><MINQTY>3</MINQTY></ITEM>
  <ITEM><ITEMTYPE>M</ITEMTYPE><ITEMID>cty0001</ITEMID><MINQTY>1</MINQTY></ITEM>
</INVENTORY>
"""


def _line(colour, part, x=0):
    return f"1 {colour} {x} 0 0 1 0 0 0 1 0 0 0 1 {part}\n"


def _mpd() -> str:
    """A main model placing a red submodel of five 3003 twice (colour 16 inherits red), the
    grey bricks, plates and slopes directly."""
    text = "0 FILE main.ldr\n0 Main model\n"
    text += "".join(_line(71, "3001.dat", i) for i in range(7))
    text += _line(4, "tower.ldr") + _line(4, "tower.ldr", 40)
    text += "".join(_line(0, "3023.dat") for _ in range(4))
    text += _line(15, "3022.dat") + _line(15, "3022.DAT")
    text += "".join(_line(4, "3039.dat") for _ in range(3))
    text += "0 NOFILE\n0 FILE tower.ldr\n"
    text += "".join(_line(16, "3003.dat", i) for i in range(5))
    return text + "0 NOFILE\n"


EXPECTED = {("3001", 71): 7, ("3003", 4): 10, ("3023", 0): 4, ("3022", 15): 2}


@pytest.mark.parametrize("name,text", [("parts.csv", REBRICKABLE), ("set.csv", SET_CSV),
                                       ("wanted.xml", BRICKLINK), ("model.mpd", _mpd())])
def test_the_same_box_in_every_format(tmp_path, name, text):
    path = tmp_path / name
    path.write_text(text)
    inv = inventory.read([path])
    assert inv.counts == EXPECTED
    slopes = [r for r in inv.ignored if r["part"] == "3039"]
    assert len(slopes) == 1 and slopes[0]["count"] == 3
    assert "not one of the plates and bricks" in slopes[0]["why"]
    assert inv.designs() == {"3001": 7, "3003": 10, "3023": 4, "3022": 2}


def test_files_are_summed_and_formats_sniffed(tmp_path):
    a, b = tmp_path / "a.txt", tmp_path / "b"
    a.write_text(REBRICKABLE)
    b.write_text(BRICKLINK)
    inv = inventory.read([a, b])
    assert inv.counts == {k: 2 * v for k, v in EXPECTED.items()}
    assert any(r["why"].startswith("item type M") for r in inv.ignored)


def test_unknown_colours_are_ignored_not_errors(tmp_path):
    path = tmp_path / "odd.csv"
    path.write_text("Part,Color,Quantity\n3001,9999,2\n3001,72,1\n")
    inv = inventory.read([path])
    assert inv.counts == {("3001", 72): 1}
    assert inv.ignored[0]["colour"] == "Rebrickable 9999" and inv.ignored[0]["count"] == 2


@pytest.mark.parametrize("name,text,line", [
    ("bad.csv", "Part,Color,Quantity\n3001,71,6\n3003,red,2\n", 3),
    ("short.csv", "Part,Color,Quantity\n3001,71\n", 2),
    ("head.csv", "Design,Number\n3001,71\n", 1),
    ("bad.xml", "<INVENTORY>\n<ITEM><ITEMID>3001</ITEMID>\n</INVENTORY>\n", 3),
    ("qty.xml", "<INVENTORY>\n\n<ITEM><ITEMID>3001</ITEMID><COLOR>86</COLOR><MINQTY>x</MINQTY>"
                "</ITEM></INVENTORY>", 3),
    ("bad.ldr", "0 a model\n1 71 0 0 0 1 0 0 0 1 0 0 0 1 3001.dat\n1 71 0 0 0 1 0 0 3001.dat\n", 3),
    ("loop.mpd", "0 FILE a.ldr\n1 4 0 0 0 1 0 0 0 1 0 0 0 1 b.ldr\n0 FILE b.ldr\n"
                 "1 4 0 0 0 1 0 0 0 1 0 0 0 1 a.ldr\n", 4),
])
def test_a_malformed_file_names_its_line(tmp_path, name, text, line):
    path = tmp_path / name
    path.write_text(text)
    with pytest.raises(InputError, match=rf"{name} line {line}:"):
        inventory.read([path])


def test_a_missing_file_is_one_line(tmp_path):
    with pytest.raises(InputError, match="no such file"):
        inventory.read([tmp_path / "nothing.csv"])
