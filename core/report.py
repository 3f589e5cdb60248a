"""What a run's result says: ``report.json``, its sentences, and the time model.

:func:`document` is the ``report.json`` document of a :class:`core.pipeline.Fabrication`
(the DESIGN.md contract): the model, the grid, the bricks, stability with the force and
build-step checks, the printed parts, print times, the assembly estimate and the
speed-ups, layout quality, hollowing and the seconds per stage.  The time model is the
paper's: the maker builds the LEGO while the printer prints, then presses the printed parts
on (:func:`fabrication_seconds`); :func:`speedups` compares that with printing the whole
model.  The sentences (:func:`force_line`, :func:`print_method_words`,
:func:`slower_words`, ...) are the ones the command line, the instructions and the
workbench show.
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from core import colours, forces as forces_stage, hollow as hollow_stage
from core import inventory as inventory_stage, stability as stability_stage
from core.instructions import build_order
from core.layout import search as improve
from core.model import Layout
from core.printing import printers

#: Area (mm²) thinner than a nozzle prints from which the summary warns; smaller spots
#: (a sharp corner of the engraved letters, say) stay in report.json's thin_features.
THIN_WARNING_MM2 = 1.0


def assembly_split(fab) -> tuple[float, float]:
    """The assembly estimate as (LEGO building, printed-part insertion) seconds.

    LEGO building is ``seconds_per_brick`` per LEGO brick, insertion is
    ``seconds_per_part`` per printed part.  After an iteration
    (``--previous``) it is the rework only: each LEGO brick to take off or
    add, each reprinted part to insert.
    """
    if fab.iteration is None:
        return (build_order.assembly_seconds(fab.layout, fab.seconds_per_brick, 0.0),
                build_order.assembly_seconds(fab.layout, 0.0, fab.seconds_per_part))
    ch = fab.iteration.changes
    moves = sum(1 for b in ch["take_off"] + ch["add"] if b.get("kind", "lego") == "lego")
    return fab.seconds_per_brick * moves, fab.seconds_per_part * len(fab.iteration.reprinted)


def assembly_seconds(fab) -> float:
    """Assembly estimate: LEGO building plus printed-part insertion (:func:`assembly_split`)."""
    return sum(assembly_split(fab))


def fabrication_seconds(fab) -> float | None:
    """Wall-clock time of the faBrickated object, or None before slicing.

    As in the paper's walkthrough, the user builds the LEGO part while the
    printer prints ("the overall fabrication time was thus still bound by
    the 3D printer"), then presses the printed parts on:
    max(parts print, LEGO building) + part insertion.
    """
    if fab.print_parts is None:
        return None
    lego, insert = assembly_split(fab)
    return max(fab.print_parts.seconds, lego) + insert


def speedups(fab) -> dict[str, float] | None:
    """The speed-ups over printing the whole model, or None before slicing.

    - ``fabrication``: full print / :func:`fabrication_seconds` (LEGO built
      while the printer prints), the paper's headline figure;
    - ``printing``: full print / parts print, the paper's "improvement for
      3D printing time" of its Validation (2.44x on average there);
    - ``sequential``: full print / (parts print + whole assembly), for one
      who only starts building once the print is done.

    After an iteration these compare printing the new version whole with
    reprinting the changed parts and the rework (the paper's "faster
    iteration").
    """
    if fab.print_full is None or fab.print_parts is None:
        return None
    full, parts = fab.print_full.seconds, fab.print_parts.seconds
    return {"fabrication": full / max(fabrication_seconds(fab), 1e-9),
            "printing": full / max(parts, 1e-9) if parts > 0 else float("inf"),
            "sequential": full / max(parts + assembly_seconds(fab), 1e-9)}


def incomplete_studs(part) -> dict:
    """A printed part's incomplete studs for the report: cells (0-based ``i,j,k``, as
    layout.json), the layers they are in (counted from 1) and a sentence."""
    cells = [[int(v) for v in c.split(",")] for c in part.incomplete_studs]
    layers = sorted({k + 1 for _, _, k in cells})
    n = len(cells)
    return {"part": part.id, "count": n, "cells": cells, "layers": layers,
            "why": f"printed part {part.id} has {n} incomplete stud{'s' if n != 1 else ''} on its "
                   f"top in layer{'s' if len(layers) != 1 else ''} {', '.join(map(str, layers))}: "
                   "the LEGO brick above does not clamp there, so the part is held less firmly "
                   "(connectors are switched off, so the part is cut exactly)"}


def print_method_words(full_method: str, parts_method: str) -> str:
    """How the print times were found, in a maker's words (from the estimates' methods)."""
    def one(method: str) -> str:
        if method.startswith("estimate"):
            why = ("PrusaSlicer is not installed" if "not found on PATH" in method
                   else "the slicer chosen is not found" if "not found" in method
                   else "slicing is switched off" if "FABRICKATOR_SLICER" in method or "disabled" in method
                   else "the slicer failed on it")
            return f"estimated from the volume, surface and layers printed ({why})"
        if method.startswith("nothing"):
            return "nothing to print"
        slicer = re.match(r"[^(;]*(?:\([^)]*\))?", method).group(0).strip()
        return "sliced with " + slicer.replace("prusa-slicer", "PrusaSlicer")
    full, parts = one(full_method), one(parts_method)
    text = (f"Whole part and printed parts: {full}." if full == parts
            else f"Whole part: {full}. Printed parts: {parts}.")
    if "estimated" in text:
        text += (" For a slicer's times, have PrusaSlicer installed and slice them (in FreeCAD the "
                 "Report's Slice print times button; on the command line, fabricate slices them "
                 "unless --slicer none).")
    return text


def stress_title(fab) -> str:
    """The title of ``stress.png``: what the colours mean and the verdict."""
    f = fab.forces
    worst = "infinite" if not np.isfinite(f.max_utilisation) else f"{f.max_utilisation:.2f}"
    verdict = "stands" if f.stable else f"{len(f.failing_bricks)} brick(s) fail"
    return (f"{Path(fab.model.path).name} on a {f.ground}, {f.mass_g:.0f} g: {verdict}, worst "
            f"utilisation {worst} (dark 0, red 1, white fails)")


def build_stability(order: build_order.BuildOrder, bodies: int, layout: Layout | None = None) -> dict:
    """The report's ``stability.build``: does the partial build (of ``bodies`` bricks and
    printed parts) stand after every step; where steps were checked by the brick graph
    only (a NaN utilisation), how many, from which step, and why; the props it needs
    (with their words when ``layout`` is given)."""
    values = np.asarray(order.utilisation, dtype=float)
    graph_only = np.flatnonzero(np.isnan(values))
    worst = float(np.max(values[~np.isnan(values)], initial=0.0))
    extra = {} if not len(graph_only) else {
        "graph_only_steps": int(len(graph_only)), "first_graph_only_step": int(graph_only[0]) + 1,
        "graph_only_why": order.graph_only_why or forces_stage.graph_only_why(bodies)}
    return {"stands_every_step": not order.unstable,
            "worst_step_utilisation": None if not np.isfinite(worst) else round(worst, 4),
            **extra,
            "unstable_steps": list(order.unstable),
            "fragile_steps": [n + 1 for n, u in enumerate(order.utilisation)
                              if build_order.FRAGILE < u <= forces_stage.FAIL_ABOVE],
            "steps_moved_earlier": order.moved,
            "props": [dict(p, words=build_order.prop_words(layout, p)) if layout is not None
                      else dict(p) for p in order.props],
            **({} if order.finished is None else {"finished_with_props": dict(order.finished)}),
            "explain": "Each step's partial build is checked with the same forces, without what "
                       "the object carries. A step is put earlier than planned when that lets the "
                       "build stand; where no order does, a prop (a stack of 1x1 bricks and "
                       "plates on the table, cell i,j,k as layout.json) holds the step's brick up "
                       "until the build stands without it; an unstable step needs a hand to hold "
                       "it until the next steps are on; a fragile step stands with its hardest "
                       f"joint above {build_order.FRAGILE:g} of its clutch."}


def build_block(fab) -> dict:
    """``{"build": ...}`` for the report's stability: the step-by-step check, or why there
    is none; empty when the forces were not asked for."""
    if fab.order.utilisation:
        return {"build": build_stability(fab.order, fab.forces.bodies, fab.layout)}
    why = None if fab.forces is None else forces_stage.build_unchecked(fab.forces)
    return {} if why is None else {"build": {"checked": False, "why": why}}


def document(fab) -> dict:
    """The ``report.json`` document for a fabrication (DESIGN.md contract)."""
    by_part: dict[str, int] = {}
    for b in fab.layout.bricks:
        by_part[b.part] = by_part.get(b.part, 0) + 1
    lego = sum(1 for b in fab.layout.bricks if b.kind == "lego")
    m, st = fab.model, fab.stability
    incomplete = sum(len(p.incomplete_studs) for p in fab.printed)
    full, plate = fab.print_full, fab.print_parts
    gains = speedups(fab)
    making = fabrication_seconds(fab)
    lego_s, insert_s = assembly_split(fab)
    bounds = m.mesh.bounds
    return {
        "model": {
            "path": str(m.path),
            "format": m.format,
            "units": fab.request.units,
            "scale": float(fab.request.scale),
            "up": fab.request.up,
            "triangles": int(m.triangles),
            "watertight": bool(m.watertight),
            "repaired": list(m.repaired),
            "warnings": list(m.warnings),
            "bbox_mm": [round(float(v), 4) for v in (bounds[1] - bounds[0])],
            "bounds_mm": [[round(float(v), 4) for v in row] for row in bounds],
        },
        "grid": {
            "origin_mm": [round(float(v), 6) for v in fab.grid.origin],
            "shape": list(fab.grid.shape),
            "cell_mm": [float(c) for c in fab.grid.cell],
            "alignment": "z from the part's lowest point; x and y centred on the part's bounding box"
            if fab.fit is None or fab.fit.shift_mm == (0.0, 0.0) else
            "z from the part's lowest point; x and y shifted from centred on the part's bounding "
            "box so that the high-res regions mark the least of the model",
            **({} if fab.fit is None else {"fit": fab.fit.to_json()}),
        },
        "plates": fab.grid.count,
        "bricks": {
            "total": len(fab.layout.bricks),
            "lego": lego,
            "printed": len(fab.layout.bricks) - lego,
            "by_part": dict(sorted(by_part.items())),
            "per_cell": round(len(fab.layout.bricks) / max(fab.grid.count, 1), 4),
        },
        "brick_set": [p.number for p in fab.parts],
        "seed": fab.seed,
        "stability": {
            "regions": st.regions,
            "components": st.components,
            "weak_points": len(st.weak_points),
            "weak_point_bricks": list(st.weak_points),
            "weak_points_holding_only_leaf_bricks": len(st.leaf_supports),
            "unconnectable": list(st.unconnectable),
            "incomplete_studs": incomplete,
            "weak_point_details": list(st.weak_details),
            "incomplete_stud_parts": [incomplete_studs(p) for p in fab.printed if p.incomplete_studs],
            "explain": {"weak_point": stability_stage.WEAK_POINT_MEANS,
                        "incomplete_stud": stability_stage.INCOMPLETE_STUD_MEANS},
            **({} if fab.forces is None else {"force": fab.forces.to_json()}),
            **build_block(fab),
            **({} if fab.reinforced is None else {"reinforce": fab.reinforced.to_json()}),
        },
        "high_res": dict(fab.marks),
        "printed_parts": [p.to_json() for p in fab.printed],
        "print_time_s": None if full is None else {
            "full_model": round(full.seconds, 1),
            "printed_parts": round(plate.seconds, 1),
            "full_model_pose": full.pose, "full_model_supports": bool(full.supports),
            "method": full.method if full.method == plate.method
            else f"full model: {full.method}; printed parts: {plate.method}",
            "method_words": print_method_words(full.method, plate.method),
            "print_plates": len(fab.plates or ()), "full_model_on_enlarged_bed": full.enlarged_bed,
        },
        "printer": {**printers.described(fab.request).to_json(), "chosen": fab.printer is not None},
        "fit": {"stud_fit": fab.interface.stud_fit, "socket_fit": fab.interface.socket_fit,
                "source": fab.request.fit_source},
        "assembly_s": round(assembly_seconds(fab), 1),
        "assembly_split_s": {"lego": round(lego_s, 1), "insert_printed_parts": round(insert_s, 1)},
        "fabrication_s": None if making is None else round(making, 1),
        "seconds_per_brick": fab.seconds_per_brick,
        "seconds_per_part": fab.seconds_per_part,
        "speedup": None if gains is None else round(gains["fabrication"], 3),
        "speedups": None if gains is None else {
            "definition": "fabrication: full print / (max(parts print, LEGO building) + inserting "
                          "the printed parts); printing: full print / parts print; sequential: "
                          "full print / (parts print + all assembly)",
            **{k: (None if v == float("inf") else round(v, 3)) for k, v in gains.items()}},
        "layout_quality": dict(fab.layout_quality),
        "timings_s": dict(fab.timings_s),
        "hollow": hollow_report(fab),
        "notes": list(fab.notes),
        "warnings": list(fab.warnings) + slower_words(fab, gains, making),
        **({} if fab.iteration is None else {"changes": fab.iteration.changes}),
        **({} if fab.inventory is None else {"inventory": {
            **inventory_stage.summary(fab.colouring), "inventory_only": fab.request.inventory_only,
            "bought_colour": colours.name(colours.by_name(fab.request.colour)),
            **fab.inventory.to_json()}}),
    }


def hollow_report(fab) -> dict | None:
    """The ``hollow`` block of the report: what the hollow stage did (:mod:`core.hollow`) and
    the bricks and assembly time with and without hollowing (an iteration hollows as its
    previous version: :func:`core.hollow.as_before`).

    For a hollowed run, ``bricks`` and ``assembly_s`` hold the LEGO bricks ``built`` and
    the solid part's: ``solid``, its real bricks when the driver laid it out too
    (:func:`core.hollow.solid_layout_wanted`), by the fast layout, which the improve stage
    did not shorten (``solid_layout`` is ``"fast"``); else (``"none"``: a solid part too
    big to lay out as well, or an iteration, which lays out only what changed)
    ``solid_at_least``, a lower bound: no catalog part covers more cells than the largest,
    so it needs at least its cells over the largest part's cells, which can be far below
    a real layout's bricks (an uneven part needs many small ones).  ``compare`` says it in a
    sentence, and why a bound.
    """
    h = fab.hollowing
    if h is None:
        return None
    lego = sum(1 for b in fab.layout.bricks if b.kind == "lego")
    doc = h.to_json()
    doc.update(bricks={"built": lego}, assembly_s={"built": round(lego * fab.seconds_per_brick, 1)})
    if not h.on:
        return doc
    largest = max(p.footprint[0] * p.footprint[1] * p.layers for p in fab.parts)
    if h.bricks_solid is not None:
        solid, key, how = h.bricks_solid, "solid", "fast"
        words = f"solid, {solid:,} bricks (fast layout, not improved)"
        bound = ""
    else:
        solid, key, how = -(-h.solid_cells // largest), "solid_at_least", "none"
        words = f"solid at least {solid:,} bricks"
        bound = (" (a lower bound: a new version is laid out only where it changed)"
                 if fab.iteration is not None else
                 f" (a lower bound: its {h.solid_cells:,} cells are more than the "
                 f"{hollow_stage.SOLID_LAYOUT_MAX_CELLS:,} laid out solid beside a shell)")
    doc["bricks"][key] = solid
    doc["assembly_s"][key] = round(solid * fab.seconds_per_brick, 1)
    doc["solid_layout"] = how
    doc["compare"] = (f"{lego:,} LEGO bricks, about {duration_words(lego * fab.seconds_per_brick)} to build; "
                      f"{words} and {duration_words(solid * fab.seconds_per_brick)}{bound}")
    return doc


def force_line(force: dict | None, build: dict | None = None) -> str:
    """The force check of report.json (``stability.force``) in one line; with the build
    check (``stability.build``), what the props left in the finished build do."""
    if not force:
        return "not checked"
    if not force.get("checked", True):
        return f"not checked: {force['unchecked_why']}"
    failing = len(force["failing_bricks"])
    finished = (build or {}).get("finished_with_props")
    return (forces_stage.verdict_words(force) + (f", {failing} failing brick(s)" if failing else "")
            + (f"; {build_order.finished_words(finished, force)}" if finished else ""))


def steps_record(order: build_order.BuildOrder, layout: Layout) -> dict:
    """The build order as plain JSON data: its steps, the bricks no step attaches, the
    printed parts placed early, each step's warning (by step number) and the props."""
    from core.instructions import page as instructions

    return {"steps": [s.to_json() for s in order.steps],
            "unattached": list(order.unattached),
            "early_parts": list(order.early_parts),
            "warnings": {str(n): text for n, text in instructions.step_warnings(order, layout).items()},
            "props": list(order.props)}


def slower_words(fab, gains: dict | None, making: float | None) -> list[str]:
    """A warning when printing the whole model is faster than the printed parts with the
    LEGO built meanwhile (a speed-up under 1), saying what to mark less of."""
    if gains is None or making is None or gains["fabrication"] >= 1.0:
        return []
    what = ("the suggested regions mark too much of this model for a speed-up: drop some "
            "(python -m core suggest --out lists them) or print it whole"
            if fab.marks.get("suggested") else "mark less to be printed, or print it whole")
    return [f"printing the whole model ({duration_words(fab.print_full.seconds)}) is faster than "
            f"the printed parts with the LEGO built meanwhile ({duration_words(making)}): {what}"]


def duration_words(seconds: float | None) -> str:
    """``seconds`` as ``3 h 05 min`` or ``12 min``; ``-`` for None."""
    if seconds is None:
        return "-"
    m = int(round(float(seconds) / 60.0))
    return f"{m // 60} h {m % 60:02d} min" if m >= 60 else f"{m} min"


def summary(doc: dict, out) -> tuple[list[str], list[str]]:
    """The short summary of one fabricate run whose ``report.json`` is ``doc``, written to
    ``out``: ``(lines, notes)``, the lines for stdout and the warnings and notes
    (``"warning: ..."``, ``"note: ..."``) for stderr."""
    lines: list[str] = []
    notes: list[str] = []
    if doc["model"]["repaired"]:
        notes.append(f"note: the model was repaired: {'; '.join(doc['model']['repaired'])}")
    for warning in doc["model"]["warnings"]:
        notes.append(f"warning: {warning}")
    for warning in doc.get("warnings", ()):
        notes.append(f"warning: {warning}")
    for note in doc.get("notes", ()):
        notes.append(f"note: {note}")
    st, br = doc["stability"], doc["bricks"]
    lines.append(f"{doc['plates']} cells -> {br['total']} bricks "
                 f"({', '.join(f'{n}x {p}' for p, n in br['by_part'].items())}); "
                 f"{st['components']} component(s) for {st['regions']} region(s), "
                 f"{st['weak_points']} weak point(s); written to {out}")
    if doc.get("inventory"):
        lines.append(inventory_stage.summary_words(doc["inventory"])
                     + (f"; {doc['inventory']['ignored_parts']} owned part(s) ignored (not plates or "
                        f"bricks of the catalog, report.json inventory.ignored)"
                        if doc["inventory"]["ignored_parts"] else ""))
    bound = improve.bound_words(doc.get("layout_quality") or {})
    if bound:
        lines.append(bound)
    more, warned = _force_summary(st)
    lines += more
    notes += warned
    hollow = doc.get("hollow")
    if hollow and (hollow["on"] or hollow["setting"] != "auto" or "laid_out_both" in hollow):
        lines.append(hollow["why"] + (f"; {hollow['compare']}" if hollow.get("compare") else ""))
    suggested = doc.get("high_res", {}).get("suggested")
    if suggested is not None:
        kinds: dict = {}
        for region in suggested["regions"]:
            for feature in region["features"]:
                kinds[feature["kind"]] = kinds.get(feature["kind"], 0) + 1
        lines.append(f"{len(suggested['regions'])} suggested region(s) marked (cells holding "
                     f"{suggested['share_of_volume']:.0%} of the part, {suggested['share_of_cells']:.0%} "
                     f"of the cells; report.json high_res.suggested): "
                     + (", ".join(f"{n} {kind}(s)" for kind, n in sorted(kinds.items())) or "nothing found"))
    fit = doc["grid"].get("fit")
    if fit and any(fit["shift_mm"]):
        vol = fit["marked_model_mm3"]
        lines.append(f"grid shifted {fit['shift_mm'][0]:g}, {fit['shift_mm'][1]:g} mm in x, y: the high-res "
                     f"cells hold {vol['fitted']:.0f} mm³ of the part instead of {vol['centred']:.0f}")
    more, warned = _parts_summary(doc)
    lines += more
    notes += warned
    ch = doc.get("changes")
    if ch:
        t = ch["transform"]
        if not t.get("confident", True):
            notes.append(f"warning: {t.get('message')}")
        lines.append(f"changes: {ch['cells_added']} cell(s) added, {ch['cells_removed']} removed; "
                     f"{ch['bricks_kept']} brick(s) kept, {len(ch['take_off'])} to take off, "
                     f"{len(ch['add'])} to add; reprint {', '.join(ch['parts_reprinted']) or 'nothing'} "
                     f"(see changes.html)")
    return lines, notes


def _force_summary(st: dict) -> tuple[list[str], list[str]]:
    """:func:`summary`'s lines and warnings on the force check and the build steps."""
    lines: list[str] = []
    notes: list[str] = []
    force = st.get("force")
    if force and not force.get("checked", True):
        lines.append(f"force check skipped: {force['unchecked_why']}")
    elif force:
        lines.append(forces_stage.verdict_words(force)
                     + (f", {len(force['failing_bricks'])} failing brick(s) (report.json stability.force)"
                        if force["failing_bricks"] else "")
                     + (f"; it rests leaning {force['rests_tilted_deg']:.0f}° on its lower points"
                        if force.get("rests_tilted_deg", 0) >= 1 else ""))
        for topple in force.get("topples", ()):
            notes.append(f"warning: {topple['why']}")
        build = st.get("build") or {}
        if build.get("checked") is False:
            lines.append(f"build steps not force-checked: {build['why']}")
        elif build.get("graph_only_steps"):
            lines.append(f"{build['graph_only_steps']} build step(s) from step {build['first_graph_only_step']} "
                         f"not force-checked: {build['graph_only_why']}")
        props = build.get("props", ())
        if props:
            lines.append(f"{len(props)} prop(s) hold overhanging bricks while the build grows "
                         "(instructions.html says at which steps; report.json stability.build.props):")
            for prop in props[:3]:
                lines.append(f"  {prop['words']}")
            if len(props) > 3:
                lines.append(f"  and {len(props) - 3} more")
        if build.get("finished_with_props"):
            lines.append(build_order.finished_words(build["finished_with_props"], force))
        for step in build.get("unstable_steps", ())[:5]:
            notes.append(f"warning: build step {step['step']}: {step['why']}")
    return lines, notes


def _parts_summary(doc: dict) -> tuple[list[str], list[str]]:
    """:func:`summary`'s lines and warnings on the printed parts, their times and printer."""
    lines: list[str] = []
    notes: list[str] = []
    st = doc["stability"]
    if doc["printed_parts"]:
        pt = doc["print_time_s"] or {}
        lines.append(f"{len(doc['printed_parts'])} printed part(s), {st['incomplete_studs']} incomplete "
                     f"stud(s); print {pt.get('full_model')} s whole vs {pt.get('printed_parts')} s parts, "
                     f"{doc['assembly_s']} s assembly (LEGO built while it prints): "
                     f"{doc['fabrication_s']} s, speed-up {doc['speedup']}")
        if doc.get("printer"):
            p = doc["printer"]
            plates = pt.get("print_plates", 1)
            lines.append(f"printed on: {p['printer']} ({p['print_preset']}, {p['filament']}), {plates} plate"
                         f"{'s' if plates != 1 else ''}; fit: stud {doc['fit']['stud_fit']:+g}, socket "
                         f"{doc['fit']['socket_fit']:+g} mm ({doc['fit']['source']})")
    for part in doc["printed_parts"]:
        if not part["engaged"]["clamps"]:
            notes.append(f"warning: printed part {part['id']} does not clamp: {part['engaged']['why']}")
        thin = part.get("thin_features") or {}
        if thin.get("area_mm2", 0.0) >= THIN_WARNING_MM2:
            spot = thin["spots"][0]
            notes.append(f"warning: printed part {part['id']} has {thin['area_mm2']:.1f} mm² thinner than "
                         f"{thin['limit_mm']:g} mm (a nozzle cannot print it), thinnest {thin['thinnest_mm']:g} mm "
                         f"near {', '.join(f'{v:g}' for v in spot['centre_mm'])}")
    return lines, notes


def headlines(doc: dict, steps: int) -> list[str]:
    """The headline numbers of a result whose ``report.json`` is ``doc``, built in ``steps``
    assembly steps, one short line each, in words (the workbench's Report)."""
    bricks, st = doc["bricks"], doc["stability"]
    weak, studs = st["weak_points"], st["incomplete_studs"]
    lines = [f"{bricks['total']} bricks ({bricks['lego']} LEGO, {bricks['printed']} printed) "
             f"from {doc['plates']} plates; {steps} assembly steps",
             ("the bricks hold together as one structure" if st["components"] == st.get("regions", 1)
              else f"the bricks fall into {st['components']} separate pieces"),
             (f"{weak} weak point{'s' if weak != 1 else ''} (a brick that alone joins two parts "
              "of the build)" if weak else "no weak points"),
             (f"{studs} incomplete stud{'s' if studs != 1 else ''} on printed parts (a LEGO brick "
              "above does not clamp there)" if studs else "every stud of the printed parts is complete")]
    if doc.get("inventory"):
        lines.append(inventory_stage.summary_words(doc["inventory"]))
    quality = doc.get("layout_quality") or {}
    if "one_piece" in (quality.get("lower_bound") or {}):
        lines.append(improve.bound_words(quality))
    if st.get("force"):
        lines.append(f"force check: {force_line(st['force'], st.get('build'))}")
    times = doc.get("print_time_s")
    if times:
        lines.append(f"print time: whole part {duration_words(times['full_model'])}, printed parts "
                     f"{duration_words(times['printed_parts'])} + assembly {duration_words(doc['assembly_s'])}")
    if doc.get("speedup"):
        gains = doc["speedups"]
        printing = f"{gains['printing']:.2f}x" if gains.get("printing") else "nothing to print"
        lines.append(f"speed-up {doc['speedup']:.2f}x over printing the whole part, building the "
                     f"LEGO while the parts print (printing alone {printing}; building after "
                     f"printing {gains['sequential']:.2f}x)")
    return lines
