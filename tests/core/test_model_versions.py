"""Which model file is a version of which: one rule (core.watch.model_name / same_model)
for the CLI's watch and the workbench's Watch folder command."""

from __future__ import annotations

import pytest

from core import watch


@pytest.mark.parametrize("name", [
    "bracket.stl", "bracket_v1.stl", "bracket_v2.stl", "Bracket_V2.STL", "bracket-3.stl",
    "bracket.001.stl", "bracket rev4.stl", "bracket_v1.2.stl", "bracket (1).stl",
    "bracket(2).stl", "bracket_v2 (1).stl", "bracket.step", "bracket.3mf",
])
def test_versioned_names_are_versions_of_the_model(tmp_path, name):
    assert watch.model_name(name).casefold() == "bracket"
    assert watch.same_model(tmp_path / name, tmp_path / "bracket.stl")


@pytest.mark.parametrize("name, model", [
    ("bracket2.stl", "bracket2"), ("gear2.stl", "gear2"), ("m3.stl", "m3"),
    ("bracket_final.stl", "bracket_final"), ("my-part.stl", "my-part"),
    ("part_2_3.stl", "part_2"), ("_2.stl", "_2"), ("v2.stl", "v2"),
])
def test_digits_without_a_separator_belong_to_the_name(name, model):
    assert watch.model_name(name) == model


def test_case_is_kept_in_the_name_and_ignored_in_the_match(tmp_path):
    assert watch.model_name("Bracket_v3.stl") == "Bracket"
    assert watch.same_model(tmp_path / "Bracket_v3.stl", tmp_path / "bracket.obj")


def test_other_models_and_other_folders_are_not_versions(tmp_path):
    assert not watch.same_model(tmp_path / "bracket2.stl", tmp_path / "bracket.stl")
    assert not watch.same_model(tmp_path / "gear.stl", tmp_path / "bracket.stl")
    (tmp_path / "a").mkdir()
    assert not watch.same_model(tmp_path / "a" / "bracket_v2.stl", tmp_path / "bracket.stl")


def test_model_key_groups_the_versions_of_a_folder(tmp_path):
    names = ["bracket.stl", "gear.stl", "bracket_v2.stl", "Gear (1).stl", "bracket2.stl"]
    groups: dict = {}
    for name in names:
        groups.setdefault(watch.model_key(tmp_path / name), []).append(name)
    assert sorted(groups.values()) == [["bracket.stl", "bracket_v2.stl"], ["bracket2.stl"],
                                       ["gear.stl", "Gear (1).stl"]]


def test_each_model_of_a_watch_iterates_on_its_own_last_result(tmp_path):
    versions = watch.Versions(first="earlier-out")
    assert versions.previous(tmp_path / "bracket.stl") == "earlier-out"
    versions.record(tmp_path / "bracket.stl", "out/bracket-1")
    assert versions.previous(tmp_path / "gear.stl") is None
    versions.record(tmp_path / "gear.stl", "out/gear-2")
    assert versions.previous(tmp_path / "bracket_v2.stl") == "out/bracket-1"
    versions.record(tmp_path / "bracket_v2.stl", "out/bracket_v2-3")
    assert versions.previous(tmp_path / "Bracket (1).stl") == "out/bracket_v2-3"
    assert versions.previous(tmp_path / "gear-2.obj") == "out/gear-2"
    assert versions.previous(tmp_path / "bracket2.stl") is None
    assert watch.Versions().previous(tmp_path / "bracket.stl") is None
