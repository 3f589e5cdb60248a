"""Tests of the time model of core.report: assembly split, fabrication time and speed-ups."""

from types import SimpleNamespace

import pytest

from core import report as reporting
from core.printing.estimate import PrintEstimate


def _fab(lego: int, parts: int, full_s: float, parts_s: float | None, iteration=None):
    bricks = [SimpleNamespace(kind="lego", printed_part=None) for _ in range(lego)]
    for p in range(parts):
        bricks += [SimpleNamespace(kind="printed", printed_part=f"P{p + 1}") for _ in range(3)]
    return SimpleNamespace(
        layout=SimpleNamespace(bricks=bricks), iteration=iteration,
        seconds_per_brick=10.0, seconds_per_part=30.0,
        print_full=None if parts_s is None else PrintEstimate(full_s, "test", None),
        print_parts=None if parts_s is None else PrintEstimate(parts_s, "test", None))


def test_printer_bound_fabrication_is_print_plus_insertion():
    fab = _fab(lego=100, parts=2, full_s=36000.0, parts_s=3000.0)
    assert reporting.assembly_split(fab) == (1000.0, 60.0)
    assert reporting.assembly_seconds(fab) == 1060.0
    assert reporting.fabrication_seconds(fab) == 3060.0
    gains = reporting.speedups(fab)
    assert gains["fabrication"] == pytest.approx(36000 / 3060)
    assert gains["printing"] == pytest.approx(12.0)
    assert gains["sequential"] == pytest.approx(36000 / 4060)


def test_builder_bound_fabrication_is_building_plus_insertion():
    fab = _fab(lego=600, parts=1, full_s=36000.0, parts_s=1200.0)
    assert reporting.fabrication_seconds(fab) == 6000.0 + 30.0
    gains = reporting.speedups(fab)
    assert gains["fabrication"] == pytest.approx(36000 / 6030)
    assert gains["fabrication"] >= gains["sequential"]


def test_nothing_printed_and_not_sliced():
    fab = _fab(lego=50, parts=0, full_s=9000.0, parts_s=0.0)
    assert reporting.fabrication_seconds(fab) == 500.0
    assert reporting.speedups(fab)["printing"] == float("inf")
    unsliced = _fab(lego=50, parts=1, full_s=0.0, parts_s=None)
    assert reporting.fabrication_seconds(unsliced) is None and reporting.speedups(unsliced) is None


def test_iteration_counts_the_rework_only():
    changes = {"take_off": [{"kind": "lego"}, {"kind": "printed"}], "add": [{"kind": "lego"}] * 3}
    iteration = SimpleNamespace(changes=changes, reprinted=["P2"])
    fab = _fab(lego=300, parts=2, full_s=20000.0, parts_s=900.0, iteration=iteration)
    assert reporting.assembly_split(fab) == (40.0, 30.0)
    assert reporting.fabrication_seconds(fab) == 930.0


def test_a_run_slower_than_printing_whole_says_so():
    """Under a speed-up of 1 the report warns, by hand: 10 LEGO bricks (100 s) while parts
    print 9,000 s, plus 30 s inserting the part, against 8,000 s printed whole."""
    fab = _fab(lego=10, parts=1, full_s=8000.0, parts_s=9000.0)
    fab.marks = {}
    gains = reporting.speedups(fab)
    making = reporting.fabrication_seconds(fab)
    assert making == 9030.0 and gains["fabrication"] < 1
    words = reporting.slower_words(fab, gains, making)
    assert words == ["printing the whole model (2 h 13 min) is faster than the printed parts with "
                     "the LEGO built meanwhile (2 h 30 min): mark less to be printed, or print it "
                     "whole"]
    fab.marks = {"suggested": {"regions": []}}
    assert "the suggested regions mark too much" in reporting.slower_words(fab, gains, making)[0]
    faster = _fab(lego=10, parts=1, full_s=8000.0, parts_s=3000.0)
    faster.marks = {}
    assert reporting.slower_words(faster, reporting.speedups(faster),
                                  reporting.fabrication_seconds(faster)) == []
