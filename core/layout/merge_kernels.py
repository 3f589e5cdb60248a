"""The merge kernels (numba): plates and bricks placed on the cells of a grid by a score.

:func:`place` merges the uncovered cells of a box into parts of the given footprints,
bottom-up, per layer the brick slab and then the plate slab; each slab is merged with several
raster scans (:data:`SLAB_TRIALS`, from the layer's own :data:`LAYER_VARIANTS`) and the best
total score kept.  A part is chosen among the footprints anchored at the first uncovered cell
by a score over the weights it is given (area, joining components, seams over seams, leaves,
orphaned cells, seeded ties).  The bricks are records ``(x, y, z, sx, sy, sz, part)`` in
caller-owned arrays with a union-find of their components; :func:`label_graph` gives the
brick graph of the labels as CSR and :func:`reset_union` rebuilds the union-find.  The
kernels release the GIL (:func:`place`) and are deterministic given the noise they are passed.
"""

from __future__ import annotations

import numpy as np
from numba import njit


#: Scan variant per layer (k mod 4): bit 0 flips x, bit 1 flips y, bit 2
#: scans columns instead of rows.  Consecutive layers start from other
#: corners along other axes, so seams do not line up.
LAYER_VARIANTS = (0, 7, 1, 6)

#: Scans tried per slab, as changes to the layer's scan variant.
SLAB_TRIALS = (0, 3, 4, 7)


@njit(cache=True)
def label_graph(lab, rec, alive, n):
    """CSR ``(indptr, indices)`` of the brick graph over brick records ``0 .. n-1``.

    Looks only at the cells directly above each live brick, so the cost
    is the bricks' footprint area, not the grid's size.
    """
    nz = lab.shape[2]
    total = 0
    for b in range(n):
        if alive[b]:
            total += rec[b, 3] * rec[b, 4]
    lower = np.empty(total, dtype=np.int64)
    upper = np.empty(total, dtype=np.int64)
    stamp = np.full(n, -1, dtype=np.int64)
    m = 0
    for b in range(n):
        z = rec[b, 2] + rec[b, 5]
        if not alive[b] or z >= nz:
            continue
        for x in range(rec[b, 0], rec[b, 0] + rec[b, 3]):
            for y in range(rec[b, 1], rec[b, 1] + rec[b, 4]):
                a = lab[x, y, z]
                if a >= 0 and stamp[a] != b:
                    stamp[a] = b
                    lower[m] = b
                    upper[m] = a
                    m += 1
    indptr = np.zeros(n + 1, dtype=np.int64)
    for e in range(m):
        indptr[lower[e] + 1] += 1
        indptr[upper[e] + 1] += 1
    for v in range(n):
        indptr[v + 1] += indptr[v]
    fill = indptr[:-1].copy()
    indices = np.empty(2 * m, dtype=np.int64)
    for e in range(m):
        indices[fill[lower[e]]] = upper[e]
        fill[lower[e]] += 1
        indices[fill[upper[e]]] = lower[e]
        fill[upper[e]] += 1
    return indptr, indices


@njit(cache=True)
def _find(parent, a):
    """Union-find root of ``a`` with path halving."""
    while parent[a] != a:
        parent[a] = parent[parent[a]]
        a = parent[a]
    return a


@njit(cache=True)
def reset_union(indptr, indices, alive, parent, n):
    """Set the union-find ``parent`` to the components of the live bricks of a CSR graph.

    Every live brick points straight at the first brick of its component
    found by a depth-first search; dead bricks stay alone.
    """
    seen = np.zeros(n, dtype=np.bool_)
    stack = np.empty(n, dtype=np.int64)
    for s in range(n):
        parent[s] = s
    for s in range(n):
        if seen[s] or not alive[s]:
            continue
        seen[s] = True
        top = 0
        stack[0] = s
        while top >= 0:
            v = stack[top]
            top -= 1
            parent[v] = s
            for e in range(indptr[v], indptr[v + 1]):
                w = indices[e]
                if alive[w] and not seen[w]:
                    seen[w] = True
                    top += 1
                    stack[top] = w


@njit(cache=True)
def _fits(x0, y0, w, h, k, want, todo, lab, base):
    """Whether the footprint lies on uncovered ``todo`` cells of layer k whose group is ``want``."""
    nx, ny = lab.shape[0], lab.shape[1]
    if x0 < 0 or y0 < 0 or x0 + w > nx or y0 + h > ny:
        return False
    for x in range(x0, x0 + w):
        for y in range(y0, y0 + h):
            if not todo[x, y, k] or lab[x, y, k] >= 0 or base[x, y, k] != want:
                return False
    return True


@njit(cache=True)
def _score(x0, y0, w, h, k, layers, want, todo, base, lab, filled, parent, rec, weights, nbr):
    """Score of a footprint at layer k, ``layers`` tall; its neighbour bricks go into ``nbr``.

    Returns ``(score, number of neighbours)``.  Neighbours are the bricks
    directly below and above.  The score adds area, joined components and
    resting on several bricks; it subtracts seam cells that continue a seam
    of the layer below or above, and a leaf penalty for every brick that
    this placement would leave with a single neighbour for good: the new
    brick itself (one neighbour and no uncovered filled cell above), or a
    brick below with nothing under it whose top this footprint covers alone;
    and an orphan penalty for every free cell of the slab next to the
    footprint that it would leave without a free neighbour (only a 1x1
    part could cover it; a leaf too if nothing is filled above or below it).
    """
    nx, ny, nz = lab.shape
    nd = 0
    aligned = 0
    below = 0
    future = False
    for side in range(2):
        layer = k - 1 if side == 0 else k + layers
        if layer < 0 or layer >= nz:
            continue
        for x in range(x0, x0 + w):
            for y in range(y0, y0 + h):
                b = lab[x, y, layer]
                if b < 0:
                    if side == 1 and filled[x, y, layer]:
                        future = True
                    continue
                new = True
                for q in range(nd):
                    if nbr[q] == b:
                        new = False
                        break
                if new:
                    nbr[nd] = b
                    nd += 1
        if side == 0:
            below = nd
        for y in range(y0, y0 + h):
            for x_in, x_out in ((x0, x0 - 1), (x0 + w - 1, x0 + w)):
                if 0 <= x_out < nx and filled[x_out, y, k]:
                    a = lab[x_in, y, layer]
                    b = lab[x_out, y, layer]
                    if a >= 0 and b >= 0 and a != b:
                        aligned += 1
        for x in range(x0, x0 + w):
            for y_in, y_out in ((y0, y0 - 1), (y0 + h - 1, y0 + h)):
                if 0 <= y_out < ny and filled[x, y_out, k]:
                    a = lab[x, y_in, layer]
                    b = lab[x, y_out, layer]
                    if a >= 0 and b >= 0 and a != b:
                        aligned += 1
    roots = 0
    for q in range(nd):
        r = _find(parent, nbr[q])
        first = True
        for p in range(q):
            if _find(parent, nbr[p]) == r:
                first = False
                break
        if first:
            roots += 1
    leaves = 0
    if nd <= 1 and not future:
        leaves += 2 - nd
    for q in range(below):
        if _hangs_from(rec[nbr[q]], x0, y0, w, h, k, lab, filled):
            leaves += 1
    orphans = 0
    for x in range(x0 - 1, x0 + w + 1):
        for y in range(y0 - 1, y0 + h + 1):
            edge_x = x == x0 - 1 or x == x0 + w
            edge_y = y == y0 - 1 or y == y0 + h
            if edge_x == edge_y or not _free(x, y, k, want, todo, lab, base):
                continue
            alone = True
            for dx, dy in ((1, 0), (-1, 0), (0, 1), (0, -1)):
                u = x + dx
                t = y + dy
                inside = x0 <= u < x0 + w and y0 <= t < y0 + h
                if not inside and _free(u, t, k, want, todo, lab, base):
                    alone = False
                    break
            if alone:
                orphans += 1
                if (k == 0 or not filled[x, y, k - 1]) or (k + layers >= nz or not filled[x, y, k + layers]):
                    leaves += 1
    score = weights[0] * w * h - weights[3] * aligned - weights[6] * leaves - weights[8] * orphans
    if roots > 1:
        score += weights[1] * (roots - 1)
    if nd >= 2:
        score += weights[2]
    return score, nd


@njit(cache=True)
def _free(x, y, k, want, todo, lab, base):
    """Whether cell (x, y, k) is inside the grid, uncovered, to do and of group ``want``."""
    if x < 0 or y < 0 or x >= lab.shape[0] or y >= lab.shape[1]:
        return False
    return todo[x, y, k] and lab[x, y, k] < 0 and base[x, y, k] == want


@njit(cache=True)
def _hangs_from(r, x0, y0, w, h, k, lab, filled):
    """Whether brick record ``r`` (just below layer k) would hang from this footprint alone.

    True when nothing lies under ``r`` and every filled cell on top of it
    is inside the footprint.
    """
    bx, by, bz, sx, sy = r[0], r[1], r[2], r[3], r[4]
    for x in range(bx, bx + sx):
        for y in range(by, by + sy):
            if bz > 0 and lab[x, y, bz - 1] >= 0:
                return False
            inside = x0 <= x < x0 + w and y0 <= y < y0 + h
            if not inside and filled[x, y, k]:
                return False
    return True


@njit(cache=True, nogil=True)
def place(todo, filled, base, lab, rec, alive, count, parent,
           pw, ph, pp, bw, bh, bp, weights, noise, variant, box, trials):
    """Merge the uncovered ``todo`` cells in ``box`` into parts, bottom-up.

    Per layer first the brick cells whose group starts there (footprints
    ``bw x bh``, three layers), then the plate cells (``pw x ph``).  Each
    such slab is merged with the first ``trials`` scans of
    :data:`SLAB_TRIALS` (relative to the layer's own scan) and the one with
    the best total score, each part costing ``weights[7]``, is kept.  New bricks are appended to
    ``rec`` (x, y, z, sx, sy, sz, part), marked alive and joined in the
    union-find ``parent`` with their neighbours.
    """
    nz = lab.shape[2]
    saved = np.empty(parent.size if trials > 1 else 0, dtype=np.int64)
    demoted = np.empty((box[1] - box[0]) * (box[3] - box[2]) + 1, dtype=np.int64)
    for k in range(box[4], box[5]):
        v0 = variant ^ LAYER_VARIANTS[k % 4]
        prefer_x = ((k + variant) % 2) == 0
        for slab in range(2):
            if slab == 0:
                if bw.size == 0 or k + 3 > nz:
                    continue
                tw, th, tp, layers, want = bw, bh, bp, 3, k
            else:
                tw, th, tp, layers, want = pw, ph, pp, 1, -1
            start = count[0]
            best = -1e300
            best_t = 0
            for t in range(trials):
                if trials > 1:
                    saved[:start] = parent[:start]
                total, nd = _place_slab(k, v0 ^ SLAB_TRIALS[t], prefer_x, tw, th, tp, layers, want,
                                        todo, filled, base, lab, rec, alive, count, parent, weights,
                                        noise, box, demoted)
                if total > best:
                    best = total
                    best_t = t
                if t == trials - 1 and best_t == t:
                    break
                for b in range(start, count[0]):
                    alive[b] = False
                    for x in range(rec[b, 0], rec[b, 0] + rec[b, 3]):
                        for y in range(rec[b, 1], rec[b, 1] + rec[b, 4]):
                            for kk in range(k, k + layers):
                                lab[x, y, kk] = -1
                count[0] = start
                parent[:start] = saved[:start]
                for q in range(nd):
                    c = demoted[q]
                    x = c // lab.shape[1]
                    y = c % lab.shape[1]
                    for kk in range(k, k + 3):
                        base[x, y, kk] = k
                if t == trials - 1:
                    _place_slab(k, v0 ^ SLAB_TRIALS[best_t], prefer_x, tw, th, tp, layers, want, todo,
                                filled, base, lab, rec, alive, count, parent, weights, noise, box,
                                demoted)


@njit(cache=True)
def _place_slab(k, v, prefer_x, tw, th, tp, layers, want, todo, filled, base, lab, rec, alive,
                count, parent, weights, noise, box, demoted):
    """Merge the slab of layer k whose cells have group ``want``, scan variant ``v``.

    A raster scan takes the first uncovered cell and places the
    best-scoring footprint anchored there.  Returns ``(total score minus
    part costs, number of demoted columns)``; columns that no brick
    footprint fits become plate cells and are listed (as ``x * ny + y``) in
    ``demoted``.
    """
    x0, x1, y0, y1 = box[0], box[1], box[2], box[3]
    ny = lab.shape[1]
    fx = (v & 1) != 0
    fy = (v & 2) != 0
    by_column = (v & 4) != 0
    nbr = np.empty(64, dtype=np.int64)
    keep = np.empty(64, dtype=np.int64)
    total = 0.0
    n_demoted = 0
    n_out = (x1 - x0) if by_column else (y1 - y0)
    n_in = (y1 - y0) if by_column else (x1 - x0)
    for a in range(n_out):
        for c in range(n_in):
            if by_column:
                x = x1 - 1 - a if fx else x0 + a
                y = y1 - 1 - c if fy else y0 + c
            else:
                y = y1 - 1 - a if fy else y0 + a
                x = x1 - 1 - c if fx else x0 + c
            if not todo[x, y, k] or lab[x, y, k] >= 0 or base[x, y, k] != want:
                continue
            best = -1e300
            bo = -1
            bx = 0
            by = 0
            bn = 0
            for o in range(tw.size):
                w = tw[o]
                h = th[o]
                xs = x - w + 1 if fx else x
                ys = y - h + 1 if fy else y
                if not _fits(xs, ys, w, h, k, want, todo, lab, base):
                    continue
                s, nd = _score(xs, ys, w, h, k, layers, want, todo, base, lab, filled, parent, rec,
                               weights, nbr)
                if (w > h and prefer_x) or (h > w and not prefer_x):
                    s += weights[4]
                t = noise[x, y, k] + 0.6180339887 * o + 0.7548776662 * weights[9]
                s += weights[5] * (t - np.floor(t))
                if s > best:
                    best = s
                    bo = o
                    bx = xs
                    by = ys
                    bn = nd
                    for q in range(nd):
                        keep[q] = nbr[q]
            if bo < 0:
                for kk in range(k, k + 3):
                    base[x, y, kk] = -1
                demoted[n_demoted] = x * ny + y
                n_demoted += 1
                total -= 3 * weights[7]
                continue
            total += best - weights[7]
            _put(bx, by, k, tw[bo], th[bo], layers, tp[bo], keep, bn, lab, rec, alive, count, parent)
    return total, n_demoted


@njit(cache=True)
def _put(x0, y0, k, w, h, layers, part, nbr, nd, lab, rec, alive, count, parent):
    """Record a new brick, label its cells and join it with its ``nd`` neighbours ``nbr``."""
    b = count[0]
    count[0] = b + 1
    rec[b, 0] = x0
    rec[b, 1] = y0
    rec[b, 2] = k
    rec[b, 3] = w
    rec[b, 4] = h
    rec[b, 5] = layers
    rec[b, 6] = part
    alive[b] = True
    parent[b] = b
    for x in range(x0, x0 + w):
        for y in range(y0, y0 + h):
            for kk in range(k, k + layers):
                lab[x, y, kk] = b
    for q in range(nd):
        ra = _find(parent, nbr[q])
        rb = _find(parent, b)
        if ra != rb:
            parent[ra] = rb
