"""The brush panel's live estimate: the print time and speed-up a brush change would give.

A brush stroke changes which bricks are printed and how they group into parts.  Cutting and
slicing those parts takes seconds; :class:`Estimator` answers in a fraction of a second
instead, from the last result (its layout, model mesh, printed parts and their print times)
and the painted bricks:

* **Grouping.**  ``high-res``: a painted LEGO brick joins every printed part and every other
  painted brick it touches face to face (:func:`core.high_res.adjacency`, the contact
  :func:`core.high_res.groups` uses), so a separate painted group is a new part; parts stay
  apart where they were apart (a split edit holds).  ``unmark``: painted printed bricks
  become LEGO, and what is left of a part falls into its connected groups.  ``merge`` and
  ``split`` group them as :func:`core.parts.printed.merge` and :func:`core.parts.printed.split` do.
* **Features.**  Each part is cut as :func:`core.parts.printed.build_part` cuts it (manifold3d),
  with its studs, sockets and LEGO's play but without the engraved id; its volume, area and
  height along the direction its pose printed up (the largest part's pose for a group that
  took parts in; upright for a new part) make one plate of
  :func:`core.printing.estimate.plate_features`.  A stroke cuts only the parts it changed.
* **Time.**  The last result's print time (each part's ``print_s``, sliced or estimated)
  plus the calibrated estimate's change (:data:`core.printing.estimate.ESTIMATE_COEFFS`) from the
  parts as they are to the parts as changed: with nothing changed, the last result's time.
  The speed-up is the report's (:func:`core.report.speedups`, ``fabrication``) for a fresh
  build of the changed layout, against the last whole-model print time.

What it does not promise: the recompute lays out the marked cells again (bricks around them
may change), and supports, the print pose of a new part and the engraving are not counted,
so it is an estimate of the change, not a prediction of the next report.
"""

from __future__ import annotations

import dataclasses
import os
import zipfile
from collections import Counter
from dataclasses import dataclass
from io import BytesIO
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import trimesh
from scipy import sparse
from scipy.sparse.csgraph import connected_components

from core import high_res, report as reporting, result
from core.errors import InputError
from core.io.meshes import LoadedModel
from core.model import Layout
from core.parts import connectors as connectors_stage, printed
from core.parts.interfaces import Fit
from core.parts.printed_part import ModelSolid
from core.printing.estimate import ESTIMATE_COEFFS, PrintEstimate, estimate_seconds, plate_features

#: The brush modes an estimate is made for.
MODES = ("high-res", "unmark", "merge", "split")

#: The direction a part prints up in when its pose is not known: upright.
UPRIGHT = (0.0, 0.0, 1.0)


@dataclass(frozen=True)
class LastPart:
    """A printed part of the last result: its id, layout brick ids, its print time
    ``print_s`` and the direction ``up`` (model frame, unit) its print pose turned up."""

    id: str
    bricks: tuple[int, ...]
    print_s: float
    up: tuple[float, float, float] = UPRIGHT


@dataclass(frozen=True)
class Figures:
    """The printed parts' print time, the assembly and fabrication time (s), the
    speed-up (the report's ``speedup``; None without a whole-model print time), how
    many printed parts there are, and whether the whole model's time is this module's
    estimate (the last result had none)."""

    print_s: float
    assembly_s: float
    fabrication_s: float
    speedup: float | None
    parts: int
    whole_estimated: bool = False


def up_of_pose(pose: dict | None) -> tuple[float, float, float]:
    """The model-frame direction a report's part ``pose`` (its ``matrix``, model to bed)
    turns up; :data:`UPRIGHT` when there is no pose."""
    if not pose or "matrix" not in pose:
        return UPRIGHT
    row = np.asarray(pose["matrix"], dtype=float)[2, :3]
    norm = float(np.linalg.norm(row))
    return UPRIGHT if norm == 0 else tuple(float(v) for v in row / norm)


def is_sliced(method: str | None) -> bool:
    """Whether a print-time ``method`` (a part's, or a report's, also its ``"full model:
    ...; printed parts: ..."`` form) is PrusaSlicer's throughout."""
    if not method:
        return False
    ways = method.removeprefix("full model: ").split("; printed parts: ")
    return not any(way.startswith(("estimate", "nothing")) for way in ways)


def snapshot_mesh(snapshot: str | os.PathLike) -> trimesh.Trimesh:
    """The model mesh of a stored result: an iteration snapshot folder (or the output
    folder holding it) or a zip of the folder holding it (what the workbench keeps).
    InputError when it has none."""
    path = Path(snapshot)
    member = f"{result.SNAPSHOT_DIR}/model.ply"
    try:
        if path.is_dir():
            ply = path / "model.ply" if (path / "model.ply").exists() else path / member
            data = ply.read_bytes()
        else:
            with zipfile.ZipFile(path) as archive:
                data = archive.read(member)
        return result.read_ply(BytesIO(data))
    except (OSError, KeyError, ValueError, zipfile.BadZipFile) as exc:
        raise InputError(f"the stored result has no readable model mesh ({exc})") from None


class Estimator:
    """Live estimates for one last result: ``layout`` (bricks marked as printed by their
    parts), the model ``mesh`` (mm, the layout's frame), its printed ``parts``, the
    whole model's print time ``full_s`` (None when the last result has none, as before
    any part is printed: then the calibrated estimate of the model printed upright), the
    assembly settings and the stud and socket ``fit`` the parts are cut with.

    Raises InputError when the mesh is not a closed solid or a part's bricks are not
    the layout's.  It keeps the parts it cut for later strokes.
    """

    def __init__(self, layout: Layout, mesh: trimesh.Trimesh, parts: list[LastPart],
                 full_s: float | None, seconds_per_brick: float, seconds_per_part: float,
                 fit: Fit = Fit()):
        self.layout = layout
        self.parts = {p.id: p for p in parts}
        self.whole_estimated = full_s is None
        self.full_s = estimate_seconds([mesh]) if full_s is None else float(full_s)
        self.seconds_per_brick = float(seconds_per_brick)
        self.seconds_per_part = float(seconds_per_part)
        model = LoadedModel(mesh, "the stored model", "ply", len(mesh.faces), bool(mesh.is_watertight))
        self.model = ModelSolid(manifold=printed.model_solid(model).manifold)
        self.fit = fit.check()
        self.index = {b.id: n for n, b in enumerate(layout.bricks)}
        self.graph = sparse.csr_matrix(high_res.adjacency(layout))
        self.owner = {i: p.id for p in parts for i in p.bricks}
        unknown = sorted(set(self.owner) - set(self.index))
        if unknown:
            raise InputError(f"printed brick(s) {unknown[:5]} are not in the layout")
        self.cut: dict[frozenset, trimesh.Trimesh] = {}
        self.current = [(p.up, frozenset(p.bricks)) for p in parts]
        self.before = self._plate(self.current)

    # --- what one figure needs -------------------------------------------------------

    def last(self) -> Figures:
        """The last result's figures, as this estimate counts them."""
        return self._figures(sum(p.print_s for p in self.parts.values()),
                             [(p.up, frozenset(p.bricks)) for p in self.parts.values()])

    def estimate(self, painted, mode: str = "high-res") -> Figures:
        """The figures with the bricks ``painted`` (layout ids) brushed in ``mode``
        (:data:`MODES`); ValueError for another mode, InputError for an id the layout
        does not have."""
        if mode not in MODES:
            raise ValueError(f"no estimate for the {mode!r} brush")
        ids = set(high_res.check_ids(self.layout, painted))
        groups = getattr(self, "_" + mode.replace("-", "_"))(ids)
        if {g for _, g in groups} == {g for _, g in self.current}:
            return self.last()
        before = sum(p.print_s for p in self.parts.values())
        seconds = max(0.0, before + self._plate(groups) - self.before) if groups else 0.0
        return self._figures(seconds, groups)

    # --- grouping --------------------------------------------------------------------

    def _high_res(self, ids: set[int]) -> list:
        """Painted LEGO bricks join the parts and painted bricks they touch."""
        new = sorted(i for i in ids if i not in self.owner)
        names = list(self.parts) + new
        node = {name: n for n, name in enumerate(names)}
        rows, cols = [], []
        for i in new:
            for j in self.graph[self.index[i]].indices:
                other = self.layout.bricks[j].id
                if other in self.owner or other in ids:
                    rows.append(node[i])
                    cols.append(node[self.owner.get(other, other)])
        links = sparse.csr_matrix((np.ones(len(rows)), (rows, cols)), shape=(len(names), len(names)))
        _, label = connected_components(links, directed=False)
        joined: dict[int, list] = {}
        for name, c in zip(names, label):
            joined.setdefault(int(c), []).append(name)
        out = []
        for members in joined.values():
            parts = [self.parts[m] for m in members if m in self.parts]
            bricks = {i for p in parts for i in p.bricks} | {m for m in members if m not in self.parts}
            largest = max(parts, key=lambda p: (len(p.bricks), p.id), default=None)
            out.append((UPRIGHT if largest is None else largest.up, frozenset(bricks)))
        return out

    def _unmark(self, ids: set[int]) -> list:
        """Painted printed bricks become LEGO; what is left of a part splits where it falls apart."""
        out = []
        for p in self.parts.values():
            rest = sorted(set(p.bricks) - ids)
            if len(rest) == len(p.bricks):
                out.append((p.up, frozenset(p.bricks)))
                continue
            out += [(p.up, frozenset(g)) for g in high_res.groups(self.layout, rest)]
        return out

    def _merge(self, ids: set[int]) -> list:
        return self._edited(ids, printed.merge)

    def _split(self, ids: set[int]) -> list:
        return self._edited(ids, printed.split)

    def _edited(self, ids: set[int], edit) -> list:
        """The parts after the merge or split ``edit`` of the painted printed bricks, each
        printed up as the part that held most of its bricks."""
        groups = [sorted(p.bricks) for p in self.parts.values()]
        chosen = {i for i in ids if i in self.owner}
        out = []
        for g in edit(groups, chosen):
            held = Counter(self.owner[i] for i in g)
            out.append((self.parts[max(held, key=lambda k: (held[k], k))].up, frozenset(g)))
        return out

    # --- measuring -------------------------------------------------------------------

    def _mesh(self, bricks: frozenset) -> trimesh.Trimesh:
        """The part of ``bricks`` as :func:`core.parts.printed.build_part` cuts it (no id, no
        thin-feature check); cut once per set of bricks (its studs and sockets depend on
        that set alone)."""
        if bricks not in self.cut:
            ids = sorted(bricks)
            part = printed.build_part("live", [self.layout.bricks[self.index[i]] for i in ids],
                                      self.layout, self.model, self.fit,
                                      connectors_stage.find(self.layout, [ids]), engrave=False,
                                      thin=False)
            self.cut[bricks] = part.mesh
        return self.cut[bricks]

    def _plate(self, groups: list) -> float:
        """The calibrated estimate (s) of ``groups`` (up, bricks) printed on one plate."""
        if not groups:
            return 0.0
        meshes = [(up, self._mesh(bricks)) for up, bricks in groups]
        features = plate_features([abs(float(m.volume)) for _, m in meshes],
                                             [float(m.area) for _, m in meshes],
                                             [float(np.ptp(m.vertices @ np.asarray(up))) for up, m in meshes])
        return float(features @ np.asarray(ESTIMATE_COEFFS, dtype=float))

    def _figures(self, print_s: float, groups: list) -> Figures:
        """The figures of ``groups`` printed in ``print_s``: the report's speed-up of a
        fresh build of the layout with those parts (:func:`core.report.speedups`)."""
        owner = {i: f"G{n}" for n, (_, g) in enumerate(groups) for i in g}
        layout = Layout(self.layout.grid, [
            dataclasses.replace(b, kind="printed", printed_part=owner[b.id]) if b.id in owner
            else dataclasses.replace(b, kind="lego", printed_part=None) for b in self.layout.bricks])
        build = SimpleNamespace(
            print_full=PrintEstimate(self.full_s, "last", None),
            print_parts=PrintEstimate(print_s, "live estimate", None), iteration=None,
            layout=layout, seconds_per_brick=self.seconds_per_brick,
            seconds_per_part=self.seconds_per_part)
        gains = reporting.speedups(build)
        return Figures(print_s, reporting.assembly_seconds(build), reporting.fabrication_seconds(build),
                       None if gains is None else gains["fabrication"], len(groups),
                       self.whole_estimated)


def words(estimate: Figures | None, last: Figures, sliced: bool) -> str:
    """The panel's line: the estimate with the painted changes (None: nothing painted)
    and the last result's figures, sliced or estimated."""
    def figures(f: Figures) -> str:
        gain = "unknown" if f.speedup is None else f"{f.speedup:.1f}x"
        if f.whole_estimated and f.speedup is not None:
            gain += " against the whole model's estimate"
        return f"print {reporting.duration_words(f.print_s)}, speed-up {gain}"

    then = f"last {'sliced' if sliced else 'run (estimated)'}: {figures(last)}"
    if estimate is None:
        return then[0].upper() + then[1:]
    return f"Estimate with these changes: {figures(estimate)} (estimate) · {then}"
