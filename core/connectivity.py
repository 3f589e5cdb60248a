"""Connectivity of cells and bricks: the graph kernels the layout and stability stages share.

The kernels (:func:`pairs_csr`, :func:`component_labels`, :func:`articulation_points`) work on
plain CSR arrays (``indptr``, ``indices``, ``n``) and are compiled with
numba, so the layout stage can call them in its repair loop;
:func:`regions` labels the connected regions of filled cells.
"""

from __future__ import annotations

import numpy as np
from numba import njit
from scipy import ndimage

#: 6-connectivity: cells touching by a face.
FACE_STRUCTURE = ndimage.generate_binary_structure(3, 1)


@njit(cache=True)
def pairs_csr(a, b, n):
    """CSR (indptr, indices) of the undirected graph on ``n`` vertices whose edges are the
    pairs ``a[i]``-``b[i]`` (each once): a counting sort, neighbours in the pairs' order."""
    indptr = np.zeros(n + 1, dtype=np.int64)
    for i in range(a.size):
        indptr[a[i] + 1] += 1
        indptr[b[i] + 1] += 1
    for v in range(n):
        indptr[v + 1] += indptr[v]
    fill = indptr[:-1].copy()
    indices = np.empty(2 * a.size, dtype=np.int64)
    for i in range(a.size):
        indices[fill[a[i]]] = b[i]
        fill[a[i]] += 1
        indices[fill[b[i]]] = a[i]
        fill[b[i]] += 1
    return indptr, indices


@njit(cache=True)
def component_labels(indptr, indices, n):
    """Component index of every vertex of a CSR graph, numbered from 0 in vertex order."""
    comp = np.full(n, -1, dtype=np.int64)
    stack = np.empty(n, dtype=np.int64)
    c = 0
    for s in range(n):
        if comp[s] >= 0:
            continue
        comp[s] = c
        top = 0
        stack[0] = s
        while top >= 0:
            v = stack[top]
            top -= 1
            for e in range(indptr[v], indptr[v + 1]):
                w = indices[e]
                if comp[w] < 0:
                    comp[w] = c
                    top += 1
                    stack[top] = w
        c += 1
    return comp


@njit(cache=True)
def articulation_points(indptr, indices, n):
    """Boolean mask of the articulation points of a simple undirected CSR graph.

    Iterative Tarjan: a vertex is an articulation point when removing it
    leaves more components than before.
    """
    disc = np.full(n, -1, dtype=np.int64)
    low = np.zeros(n, dtype=np.int64)
    parent = np.full(n, -1, dtype=np.int64)
    pos = indptr[:-1].copy()
    stack = np.empty(n, dtype=np.int64)
    art = np.zeros(n, dtype=np.bool_)
    t = 0
    for s in range(n):
        if disc[s] >= 0:
            continue
        disc[s] = t
        low[s] = t
        t += 1
        top = 0
        stack[0] = s
        root_children = 0
        while top >= 0:
            v = stack[top]
            if pos[v] < indptr[v + 1]:
                w = indices[pos[v]]
                pos[v] += 1
                if disc[w] < 0:
                    parent[w] = v
                    disc[w] = t
                    low[w] = t
                    t += 1
                    top += 1
                    stack[top] = w
                    if v == s:
                        root_children += 1
                elif w != parent[v] and disc[w] < low[v]:
                    low[v] = disc[w]
            else:
                top -= 1
                p = parent[v]
                if p >= 0:
                    if low[v] < low[p]:
                        low[p] = low[v]
                    if p != s and low[v] >= disc[p]:
                        art[p] = True
        if root_children >= 2:
            art[s] = True
    return art


def regions(filled: np.ndarray) -> tuple[np.ndarray, int]:
    """Label the connected regions of filled cells (6-connectivity): ``(labels, count)``; 0 is empty."""
    lab, n = ndimage.label(filled, structure=FACE_STRUCTURE)
    return lab, int(n)
