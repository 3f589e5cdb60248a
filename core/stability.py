"""Stability stage: how a layout holds together.

Two bricks are connected where one sits directly on the other with
overlapping footprints (the studs of the lower one clamp into the upper
one).  :func:`brick_graph` builds that graph from the layout's cell labels,
:func:`analyse` counts its connected components against the connected
regions of filled cells, finds the weak points (bricks whose removal splits
their component: articulation points of the graph) and says, for every
region that the bricks do not hold together, why.

The graph kernels (:func:`core.connectivity.component_labels`,
:func:`core.connectivity.articulation_points`) live in :mod:`core.connectivity`,
which the layout stage (earlier in the pipeline) uses too.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy import ndimage, sparse
from scipy.sparse.csgraph import connected_components

from core.catalog import BY_NUMBER
from core.connectivity import articulation_points, regions
from core.model import Layout

@dataclass
class Stability:
    """What :func:`analyse` found out about a layout.

    ``regions``: connected regions of filled cells (6-connectivity).
    ``components``: connected components of the brick graph; a layout that
    holds together has exactly one per region.  ``weak_points``: ids of the
    bricks that are articulation points of the brick graph.
    ``leaf_supports``: those weak points that only hold single leaf bricks
    (a brick resting on, or carrying, nothing but them); every other weak
    point carries a substructure of two or more bricks.
    ``unconnectable``: one entry per region whose bricks form more than one
    component, ``{"region", "components", "cells", "reason"}``.
    """

    regions: int
    components: int
    weak_points: list[int] = field(default_factory=list)
    unconnectable: list[dict] = field(default_factory=list)
    leaf_supports: list[int] = field(default_factory=list)
    weak_details: list[dict] = field(default_factory=list)

    def to_json(self) -> dict:
        return {"regions": self.regions, "components": self.components,
                "weak_points": list(self.weak_points),
                "leaf_supports": list(self.leaf_supports),
                "unconnectable": list(self.unconnectable),
                "weak_details": list(self.weak_details)}


#: What a weak point is, in a builder's words.
WEAK_POINT_MEANS = ("A weak point is a brick that alone joins two parts of the build: take it "
                    "away and the structure falls into pieces. Everything on the far side hangs "
                    "on the studs of this one brick, so a knock or a load there can snap the "
                    "build apart.")
#: What an incomplete stud is, in a builder's words.
INCOMPLETE_STUD_MEANS = ("An incomplete stud is a place where a printed part meets a LEGO brick "
                         "above it but has no whole stud there (the part's boundary cuts it), so "
                         "that brick does not clamp onto the part.")


def brick_graph(layout: Layout, clamp: tuple[np.ndarray, np.ndarray] | None = None) -> sparse.csr_matrix:
    """Symmetric adjacency (0/1) between bricks, indexed by position in ``layout.bricks``.

    Two bricks are adjacent where one sits directly on the other with
    overlapping footprints; bricks side by side in a layer are not.
    ``clamp`` (optional, for printed bricks) is a pair of grid-shaped bool
    arrays ``(studs_ok, bottom_ok)``: a contact between cell (i, j, k) and
    the cell above counts only where ``studs_ok[i, j, k]`` (the lower
    brick's stud there is complete) and ``bottom_ok[i, j, k + 1]`` (the
    upper brick's underside there is complete); None means all complete.
    Bricks of one printed part (same ``printed_part``) are one rigid piece:
    each is adjacent to the next of its part, whatever their contact.
    """
    return _graph_of_labels(layout.labels(), len(layout.bricks), clamp, _rigid_pairs(layout))


def _rigid_pairs(layout: Layout) -> np.ndarray:
    """(m, 2) brick index pairs chaining the bricks of each printed part."""
    members: dict[str, list[int]] = {}
    for n, b in enumerate(layout.bricks):
        if b.printed_part is not None:
            members.setdefault(b.printed_part, []).append(n)
    pairs = [(a, b) for idx in members.values() for a, b in zip(idx[:-1], idx[1:])]
    return np.array(pairs, dtype=np.int64).reshape(-1, 2)


def _graph_of_labels(lab: np.ndarray, n: int,
                     clamp: tuple[np.ndarray, np.ndarray] | None = None,
                     rigid: np.ndarray | None = None) -> sparse.csr_matrix:
    """The brick graph of a grid of brick indices (-1 empty), vectorised over cells;
    ``rigid`` (m, 2) index pairs are adjacent whatever their contact."""
    lower = lab[:, :, :-1].ravel()
    upper = lab[:, :, 1:].ravel()
    touch = (lower >= 0) & (upper >= 0) & (lower != upper)
    if clamp is not None:
        studs_ok, bottom_ok = clamp
        touch &= np.asarray(studs_ok, bool)[:, :, :-1].ravel() & np.asarray(bottom_ok, bool)[:, :, 1:].ravel()
    lower, upper = lower[touch], upper[touch]
    if rigid is not None and len(rigid):
        lower, upper = np.concatenate([lower, rigid[:, 0]]), np.concatenate([upper, rigid[:, 1]])
    rows = np.concatenate([lower, upper])
    cols = np.concatenate([upper, lower])
    graph = sparse.csr_matrix((np.ones(rows.size, dtype=np.int8), (rows, cols)), shape=(n, n))
    graph.sum_duplicates()
    graph.data[:] = 1
    return graph


def analyse(layout: Layout, clamp: tuple[np.ndarray, np.ndarray] | None = None) -> Stability:
    """Count regions and brick components, find weak points and explain splits.

    ``clamp`` is passed to the brick graph (see :func:`brick_graph`): printed
    bricks connect only through their complete studs and undersides.

    Promises: ``components >= regions`` (a component never spans two
    regions); ``weak_points`` are brick ids sorted ascending; one
    ``unconnectable`` entry for every region held by more than one
    component, in region order.
    """
    filled = np.asarray(layout.grid.filled, dtype=bool)
    region_lab, n_regions = regions(filled)
    n = len(layout.bricks)
    if n == 0:
        return Stability(n_regions, 0)
    lab = layout.labels()
    graph = _graph_of_labels(lab, n, clamp, _rigid_pairs(layout))
    n_comp, comp = connected_components(graph, directed=False)
    art = articulation_points(graph.indptr.astype(np.int64), graph.indices.astype(np.int64), n)
    weak = sorted(layout.bricks[b].id for b in np.flatnonzero(art))
    leaf_only = art & ~_carries_substructure(graph)
    leaf_supports = sorted(layout.bricks[b].id for b in np.flatnonzero(leaf_only))
    details = [_weak_detail(layout, graph, int(b)) for b in np.flatnonzero(art)]
    details.sort(key=lambda d: d["brick"])
    brick_region = np.array([region_lab[b.cell] for b in layout.bricks], dtype=np.int64)
    pairs = np.unique(np.stack([brick_region, comp], axis=1), axis=0)
    per_region = np.bincount(pairs[:, 0], minlength=n_regions + 1)
    boxes = ndimage.find_objects(region_lab)
    unconnectable = []
    split = np.flatnonzero(per_region > 1)
    joined = _joined_without_clamp(layout, lab, clamp, brick_region, per_region) if split.size else {}
    for r in split:
        box = boxes[r - 1]
        region = region_lab[box] == r
        unconnectable.append({
            "region": int(r),
            "components": int(per_region[r]),
            "cells": int(np.count_nonzero(region)),
            "reason": joined.get(int(r)) or _why_split(filled[box], region, lab[box], comp, box[2].start),
        })
    return Stability(n_regions, int(n_comp), weak, unconnectable, leaf_supports, details)


def _weak_detail(layout: Layout, graph: sparse.csr_matrix, b: int) -> dict:
    """Where weak point ``b`` (index into ``layout.bricks``) is and what hangs on it.

    ``brick`` (id), ``part``, ``kind``, ``printed_part``, ``layer`` (counted
    from 1, as the instructions count), ``cell`` (0-based min cell, as
    layout.json), ``cut_off`` (the bricks of the smaller piece that falls
    away without it) and ``why``, a sentence for the builder.
    """
    brick = layout.bricks[b]
    keep = np.ones(graph.shape[0], bool)
    keep[b] = False
    idx = np.flatnonzero(keep)
    _, comp = connected_components(graph[idx][:, idx], directed=False)
    neighbours = graph.indices[graph.indptr[b]:graph.indptr[b + 1]]
    own = set(comp[np.searchsorted(idx, neighbours)].tolist())
    pieces = sorted((idx[comp == c] for c in own), key=len)
    small = pieces[0]
    touching = [n for n in neighbours if n in set(small.tolist())]
    lower = all(layout.bricks[n].cell[2] < brick.cell[2] for n in touching)
    what = (f"brick of printed part {brick.printed_part}" if brick.kind == "printed"
            else f"LEGO {BY_NUMBER[brick.part].name.lower()} {brick.part}" if brick.part in BY_NUMBER
            else f"LEGO {brick.part}")
    count = len(small)
    why = (f"The {what} in layer {brick.cell[2] + 1} (cell {brick.cell[0]}, {brick.cell[1]}) is the only "
           f"brick joining {count} brick{'s' if count != 1 else ''} {'below' if lower else 'above'} "
           f"it to the rest: without it the build falls into {len(pieces)} pieces")
    return {"brick": int(brick.id), "part": brick.part, "kind": brick.kind,
            "printed_part": brick.printed_part, "layer": int(brick.cell[2]) + 1,
            "cell": [int(v) for v in brick.cell],
            "cut_off": sorted(int(layout.bricks[n].id) for n in small), "why": why}


def _joined_without_clamp(layout: Layout, lab: np.ndarray, clamp, brick_region: np.ndarray,
                          per_region: np.ndarray) -> dict[int, str]:
    """Per region that complete studs would hold together: why it falls apart
    (printed parts meet their neighbours without studs or sockets)."""
    if clamp is None:
        return {}
    graph = _graph_of_labels(lab, len(layout.bricks), None, _rigid_pairs(layout))
    _, comp = connected_components(graph, directed=False)
    pairs = np.unique(np.stack([brick_region, comp], axis=1), axis=0)
    free = np.bincount(pairs[:, 0], minlength=per_region.size)
    out = {}
    for r in np.flatnonzero(free < per_region):
        parts = sorted({b.printed_part for b, reg in zip(layout.bricks, brick_region)
                        if reg == r and b.printed_part is not None})
        out[int(r)] = (f"printed part(s) {', '.join(parts)} meet the bricks above or below them "
                       "without studs or sockets there (connectors switched off), so they cannot "
                       "clamp; keep connectors on or mark a larger region")
    return out


def _carries_substructure(graph: sparse.csr_matrix) -> np.ndarray:
    """Per brick: is it an articulation point once all leaf bricks are removed?

    A brick that splits the graph only by cutting off single leaf bricks
    (degree 1) stops being an articulation point without them; one that
    cuts off two or more bricks stays one.
    """
    n = graph.shape[0]
    keep = np.flatnonzero(np.diff(graph.indptr) != 1)
    sub = graph[keep][:, keep].tocsr()
    art = articulation_points(sub.indptr.astype(np.int64), sub.indices.astype(np.int64), len(keep))
    out = np.zeros(n, dtype=bool)
    out[keep[np.asarray(art, dtype=bool)]] = True
    return out


def _why_split(filled: np.ndarray, region: np.ndarray, lab: np.ndarray, comp: np.ndarray,
               k0: int) -> str:
    """One sentence on why the bricks of ``region`` form several components.

    The arrays are cut to the region's bounding box, whose lowest layer is
    ``k0``.  A region of one layer is a sheet: its plates touch nothing
    above or below.  Otherwise look at the cells where two components meet
    side by side: where no such pair has both cells filled in the layer
    above or both in the layer below, no part can span the seam and the
    split is in the geometry; else a part could have bridged it and the
    layout did not manage to.
    """
    layers = np.flatnonzero(region.any(axis=(0, 1)))
    if layers.size == 1:
        xs, ys = np.nonzero(region[:, :, layers[0]])
        w, d = int(np.ptp(xs)) + 1, int(np.ptp(ys)) + 1
        return (f"layer {k0 + int(layers[0]) + 1} is a single plate layer {w} x {d} studs with nothing "
                "above or below: no part can span it, so its plates cannot be joined")
    cl = np.where(region & (lab >= 0), comp[np.maximum(lab, 0)], -1)
    seam_layers: set[int] = set()
    spannable = 0
    for axis in (0, 1):
        a = [slice(None)] * 3
        b = [slice(None)] * 3
        a[axis] = slice(None, -1)
        b[axis] = slice(1, None)
        ca, cb = cl[tuple(a)], cl[tuple(b)]
        seam = (ca >= 0) & (cb >= 0) & (ca != cb)
        both = filled[tuple(a)] & filled[tuple(b)]
        across = np.zeros_like(both)
        across[:, :, :-1] |= both[:, :, 1:]
        across[:, :, 1:] |= both[:, :, :-1]
        spannable += int(np.count_nonzero(seam & across))
        seam_layers.update(k0 + int(k) for k in np.flatnonzero(seam.any(axis=(0, 1))))
    where = ", ".join(str(k + 1) for k in sorted(seam_layers)[:6]) + (" ..." if len(seam_layers) > 6 else "")
    if spannable == 0:
        return (f"its parts touch only side by side in layer(s) {where} with nothing "
                "filled across the seam above or below: no part can span it")
    return (f"its parts touch side by side in layer(s) {where}; a part above or below "
            f"could span {spannable} seam cell(s) there but the layout did not manage to")
