"""Mesh repair: a triangle soup made into one consistently wound, outward-facing mesh,
with every repair said in words.
"""

from __future__ import annotations


import numpy as np
import trimesh
from scipy import sparse
from scipy.sparse.csgraph import connected_components

from core.errors import InputError

#: A piece of surface whose corners spread less than this across (mm, standard deviation)
#: and less than a millionth of the model's size is flat: it encloses no volume and is
#: dropped (:func:`repair`).
FLAT_MM = 1e-3


def repair(vertices: np.ndarray, faces: np.ndarray, name: str = "the model",
           report_merges: bool = True) -> tuple[trimesh.Trimesh, list[str]]:
    """A repaired mesh from finite ``vertices`` and triangle ``faces``, and what was done.

    Merges duplicate vertices (reported if ``report_merges``: an STL stores
    every corner separately, so merging is no repair there); drops
    collapsed, zero-area and duplicate faces (a zero-area face whose three
    edges each join exactly one other face is kept: it closes a T-junction
    seam and dropping it would open the surface); drops face-connected
    pieces with fewer than 4 faces or all in one plane; makes the winding
    of each piece consistent; fills 3- and 4-edge holes; turns closed
    pieces that are inside out (negative volume, not inside another piece)
    outward, with any pieces nested inside them.  Raises InputError if no
    piece is left.
    """
    done: list[str] = []
    mesh = trimesh.Trimesh(vertices=vertices, faces=faces, process=False, validate=False)
    loaded_faces = len(mesh.faces)

    referenced = int(np.count_nonzero(np.bincount(mesh.faces.ravel(), minlength=len(mesh.vertices))))
    mesh.merge_vertices(merge_tex=True, merge_norm=True)
    merged = referenced - len(mesh.vertices)
    if merged and report_merges:
        done.append(f"merged {count_words(merged, 'duplicate vertex', 'duplicate vertices')}")

    keep, collapsed, flat, duplicate = _face_filter(mesh)
    if not keep.all():
        mesh.update_faces(keep)
        if collapsed + flat:
            done.append(f"removed {count_words(collapsed + flat, 'degenerate face')}")
        if duplicate:
            done.append(f"removed {count_words(duplicate, 'duplicate face')}")
    if len(mesh.faces) == 0:
        raise InputError(f"{name}: no volume: all {loaded_faces:,} triangles are degenerate "
                         f"(zero area)")

    labels = _piece_labels(mesh)
    solid = _pieces_with_volume(mesh, labels)
    if not solid.all():
        pieces = len(solid)
        dropped_faces = int(np.count_nonzero(~solid[labels]))
        if not solid.any():
            n = len(mesh.faces)
            what = ("one piece that encloses" if pieces == 1
                    else f"{pieces:,} separate pieces that enclose")
            raise InputError(f"{name}: no volume: the {n:,} triangles form {what} nothing")
        mesh.update_faces(solid[labels])
        labels = np.unique(labels[solid[labels]], return_inverse=True)[1]
        dead = pieces - int(np.count_nonzero(solid))
        done.append(f"dropped {count_words(dead, 'loose piece')} without volume "
                    f"({count_words(dropped_faces, 'triangle')})")
    mesh.remove_unreferenced_vertices()

    flipped = np.zeros(len(mesh.faces), dtype=bool)
    if not mesh.is_winding_consistent:
        flipped = _consistent_winding(mesh)
        if flipped.any():
            f = mesh.faces.copy()
            f[flipped] = f[flipped][:, ::-1]
            mesh.faces = f

    if not mesh.is_watertight:
        before = len(mesh.faces)
        open_edges = _boundary_edge_count(mesh)
        trimesh.repair.fill_holes(mesh)
        added = len(mesh.faces) - before
        if added:
            closed_edges = open_edges - _boundary_edge_count(mesh)
            quads = max((3 * added - closed_edges) // 2, 0)
            holes = added - quads
            done.append(f"filled {count_words(holes, 'small hole')} ({count_words(added, 'triangle')})")
            flipped = np.concatenate([flipped, np.zeros(added, dtype=bool)])
            labels = _piece_labels(mesh)

    inverted = _inside_out(mesh, labels)
    if inverted.any():
        f = mesh.faces.copy()
        f[inverted] = f[inverted][:, ::-1]
        mesh.faces = f
        flipped ^= inverted
    if flipped.any():
        done.append(f"fixed face orientation "
                    f"({count_words(int(np.count_nonzero(flipped)), 'face')} flipped)")
    return mesh, done


def count_words(count: int, singular: str, plural: str | None = None) -> str:
    """``count`` and the noun, e.g. "1 face", "1,204 faces"."""
    return f"{count:,} {singular if count == 1 else plural or singular + 's'}"


def _face_filter(mesh: trimesh.Trimesh) -> tuple[np.ndarray, int, int, int]:
    """Mask of faces to keep, and the counts of collapsed, zero-area and duplicate faces."""
    f = mesh.faces
    collapsed = (f[:, 0] == f[:, 1]) | (f[:, 1] == f[:, 2]) | (f[:, 0] == f[:, 2])
    zero = ~mesh.nondegenerate_faces() & ~collapsed
    if zero.any():
        whole = f[~collapsed]
        edges = np.sort(whole[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1)
        _, inverse, counts = np.unique(trimesh.grouping.hashable_rows(edges),
                                       return_inverse=True, return_counts=True)
        seam = np.zeros(len(f), dtype=bool)
        seam[~collapsed] = (counts[inverse] == 2).reshape(-1, 3).all(axis=1)
        zero &= ~seam
    unique = mesh.unique_faces()
    keep = ~collapsed & ~zero & unique
    duplicate = int(np.count_nonzero(~unique & ~collapsed & ~zero))
    return keep, int(np.count_nonzero(collapsed)), int(np.count_nonzero(zero)), duplicate


def _piece_labels(mesh: trimesh.Trimesh) -> np.ndarray:
    """Per face, the index of its piece: faces joined through edges shared by two faces."""
    return trimesh.graph.connected_component_labels(mesh.face_adjacency,
                                                    node_count=len(mesh.faces))


def _pieces_with_volume(mesh: trimesh.Trimesh, labels: np.ndarray) -> np.ndarray:
    """Per piece, whether it may enclose volume: 4 faces or more, not all in one plane.

    Flatness is judged from the smallest principal extent of the piece's
    corners (vectorised covariance per piece): flat is at most FLAT_MM *and*
    at most a millionth of the model's size (so a long thin bar is no
    flatter than a short one, and a tiny part read in the wrong unit is not
    flat either).
    """
    pieces = int(labels.max()) + 1
    count = np.bincount(labels, minlength=pieces)
    corners = mesh.triangles.reshape(-1, 3)
    corners = corners - corners.mean(axis=0)
    if pieces == 1:
        cov = np.cov(corners.T, bias=True)[None]
    else:
        lab = np.repeat(labels, 3)
        n = 3.0 * count
        mean = np.stack([np.bincount(lab, corners[:, i], pieces) for i in range(3)], axis=1) / n[:, None]
        cov = np.empty((pieces, 3, 3))
        for i in range(3):
            for j in range(i, 3):
                cov[:, i, j] = cov[:, j, i] = (np.bincount(lab, corners[:, i] * corners[:, j], pieces)
                                               / n - mean[:, i] * mean[:, j])
    thinnest = np.sqrt(np.clip(np.linalg.eigvalsh(cov)[:, 0], 0.0, None))
    scale = float(np.linalg.norm(np.ptp(corners, axis=0)))
    return (count >= 4) & (thinnest > min(FLAT_MM, 1e-6 * scale))


def _consistent_winding(mesh: trimesh.Trimesh) -> np.ndarray:
    """Mask of faces to flip so that neighbours across each shared edge agree.

    Vectorised: a face and its flipped copy are two nodes of a "double
    cover" graph; agreeing neighbours join same-orientation nodes,
    disagreeing ones opposite nodes.  Connected components of that graph
    give each piece's two consistent orientations; the one that flips
    fewer faces wins.  Pieces that cannot be oriented (Möbius-like) are
    left alone.  (trimesh.repair.fix_winding does the same face by face in
    Python, far slower.)
    """
    f = mesh.faces
    nf = len(f)
    pairs = mesh.face_adjacency
    edge = mesh.face_adjacency_edges

    def forward(face_index: np.ndarray) -> np.ndarray:
        rows = f[face_index]
        at = np.argmax(rows == edge[:, :1], axis=1)
        return rows[np.arange(len(rows)), (at + 1) % 3] == edge[:, 1]

    agree = forward(pairs[:, 0]) != forward(pairs[:, 1])
    a, b = pairs[:, 0], pairs[:, 1]
    b_same = np.where(agree, b, b + nf)
    b_other = np.where(agree, b + nf, b)
    rows = np.concatenate([a, a + nf])
    cols = np.concatenate([b_same, b_other])
    graph = sparse.coo_matrix((np.ones(len(rows), dtype=np.int8), (rows, cols)),
                              shape=(2 * nf, 2 * nf))
    _, lab = connected_components(graph, directed=False)
    keep_lab, flip_lab = lab[:nf], lab[nf:]
    count = np.bincount(keep_lab, minlength=lab.max() + 1)
    fewer = (count[keep_lab] < count[flip_lab]) | (
        (count[keep_lab] == count[flip_lab]) & (keep_lab > flip_lab))
    return (keep_lab != flip_lab) & fewer


def _boundary_edge_count(mesh: trimesh.Trimesh) -> int:
    """Number of edges used by exactly one face."""
    return len(trimesh.grouping.group_rows(mesh.edges_sorted, require_count=1))


def _inside_out(mesh: trimesh.Trimesh, labels: np.ndarray) -> np.ndarray:
    """Mask of faces to flip so that closed pieces face outward.

    A closed piece with negative signed volume is inside out, unless it lies
    inside another closed piece (then it may be a cavity).  A nest of pieces
    is turned as a whole, following its outermost piece, so that cavities
    stay cavities.  Nesting is decided by the generalised winding number of
    one vertex of a piece with respect to each closed piece whose bounding
    box contains it; it is only computed when some closed piece has
    negative volume, for the pieces that could be in such a nest.
    """
    pieces = int(labels.max()) + 1
    tri = mesh.triangles
    if mesh.is_watertight:
        closed = np.ones(pieces, dtype=bool)
    else:
        edges_face = mesh.edges_face
        paired = np.zeros(len(edges_face), dtype=bool)
        paired[np.asarray(trimesh.grouping.group_rows(mesh.edges_sorted, require_count=2),
                          dtype=np.int64).ravel()] = True
        open_face = np.zeros(len(tri), dtype=bool)
        open_face[edges_face[~paired]] = True
        closed = np.bincount(labels, open_face, pieces) == 0
    rel = tri - tri[:, 0].mean(axis=0)
    volume = np.bincount(labels, np.einsum("ij,ij->i", rel[:, 0],
                                           np.cross(rel[:, 1], rel[:, 2])) / 6.0, pieces)
    negative = np.flatnonzero(closed & (volume < 0))
    if not len(negative):
        return np.zeros(len(tri), dtype=bool)

    corners = tri.reshape(-1, 3)
    lab3 = np.repeat(labels, 3)
    lo = np.full((pieces, 3), np.inf)
    hi = np.full((pieces, 3), -np.inf)
    np.minimum.at(lo, lab3, corners)
    np.maximum.at(hi, lab3, corners)

    def boxes_around(q: int) -> np.ndarray:
        inside = closed & (lo <= lo[q]).all(axis=1) & (hi >= hi[q]).all(axis=1)
        inside[q] = False
        return np.flatnonzero(inside)

    in_negative = np.zeros(pieces, dtype=bool)
    for n in negative:
        in_negative |= (lo >= lo[n]).all(axis=1) & (hi <= hi[n]).all(axis=1)
    order = np.argsort(labels, kind="stable")
    bounds = np.searchsorted(labels[order], np.arange(pieces + 1))
    root = np.arange(pieces)
    for q in np.flatnonzero(in_negative):
        hosts = boxes_around(q)
        if not len(hosts):
            continue
        faces = np.concatenate([order[bounds[h]:bounds[h + 1]] for h in hosts])
        point = tri[order[bounds[q]], 0]
        winding = np.bincount(labels[faces], _solid_angles(point, tri[faces]), pieces)
        holders = hosts[np.abs(winding[hosts]) > 2.0 * np.pi]
        if len(holders):
            root[q] = holders[np.argmax(np.abs(volume[holders]))]
    return (closed & (volume[root] < 0))[labels]


def _solid_angles(point: np.ndarray, tri: np.ndarray) -> np.ndarray:
    """Signed solid angle of each triangle seen from ``point`` (Van Oosterom and Strackee).

    Their sum over a closed surface is 4 pi times its winding number
    around the point.
    """
    v = tri - point
    length = np.linalg.norm(v, axis=2)
    a, b, c = v[:, 0], v[:, 1], v[:, 2]
    det = np.einsum("ti,ti->t", a, np.cross(b, c))
    den = (length[:, 0] * length[:, 1] * length[:, 2]
           + np.einsum("ti,ti->t", a, b) * length[:, 2]
           + np.einsum("ti,ti->t", b, c) * length[:, 0]
           + np.einsum("ti,ti->t", c, a) * length[:, 1])
    return 2.0 * np.arctan2(det, den)
