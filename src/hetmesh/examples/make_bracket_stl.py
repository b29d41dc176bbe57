"""Write ``l_bracket.stl``, the boundary of examples/l_bracket.toml, into this folder.

    python examples/make_bracket_stl.py          # then, for instance:
    hetmesh mesh examples/l_bracket.toml -d 0.1 -o bracket.vtu --plot bracket.png

Nothing is downloaded; the surface is computed. The part (mm) is an L-shaped angle bracket:
the L section in the x-z plane, a foot 0 <= x <= 40, 0 <= z <= 10 and a web 0 <= x <= 10,
0 <= z <= 40, extruded along y from 0 to 20; a bolt hole of radius 5 goes through the foot
along z at (x, y) = (27, 10), another through the web along x at (y, z) = (10, 27). Every
planar face is triangulated in its plane (hetmesh.tri.cdt: a constrained Delaunay
triangulation of its corners and, on a face with a hole, the hole's 48 points), every bore
wall is a band of 96 triangles; faces share their edges' points, so the surface is closed
(watertight) and turned outward: 412 triangles, written as binary STL (little-endian
float32, 50 bytes a triangle; the header names this script), byte for byte the same on
every run. ``--out PATH`` writes it elsewhere, ``--segments N`` sets the points per hole.
"""

from __future__ import annotations

import argparse
import struct
from pathlib import Path

import numpy as np

from hetmesh.tri.cdt import constrained_delaunay

#: the foot's and the web's extents (mm), the bracket's width along y, the holes' radius
FOOT, WEB, WIDTH, RADIUS = (40.0, 10.0), (10.0, 40.0), 20.0, 5.0
#: hole centres: the foot's at (x, y), the web's at (y, z)
FOOT_HOLE, WEB_HOLE = (27.0, 10.0), (10.0, 27.0)
HEADER = b"hetmesh examples/make_bracket_stl.py: l_bracket.stl, an L bracket in mm"


def _circle(center, n: int) -> np.ndarray:
    t = 2.0 * np.pi * np.arange(n) / n
    return np.column_stack([center[0] + RADIUS * np.cos(t), center[1] + RADIUS * np.sin(t)])


def _plane_face(corners, hole, n: int) -> tuple[np.ndarray, np.ndarray]:
    """Points ``(k, 2)`` and counter-clockwise triangles of a convex polygon ``corners``
    (counter-clockwise) with an optional circular hole of centre ``hole``."""
    corners = np.asarray(corners, dtype=float)
    k = len(corners)
    edges = [(i, (i + 1) % k) for i in range(k)]
    pts = corners
    inside = None
    if hole is not None:
        ring = _circle(hole, n)
        pts = np.concatenate([corners, ring])
        edges += [(k + i, k + (i + 1) % n) for i in range(n)]
        c = np.asarray(hole, dtype=float)
        def inside(q):  # noqa: E306 - outside the hole (the polygon is convex)
            return np.linalg.norm(np.asarray(q) - c, axis=1) > RADIUS
    tri = constrained_delaunay(pts, np.asarray(edges), inside=inside)
    return pts, np.asarray(tri, dtype=np.int64)


def bracket_surface(n: int = 48) -> tuple[np.ndarray, np.ndarray]:
    """The bracket's surface: points ``(N, 3)`` and outward triangles ``(M, 3)``."""
    fx, fz = FOOT
    wx, wz = WEB
    w = WIDTH
    tris: list[np.ndarray] = []

    def add(p3: np.ndarray, t: np.ndarray, outward) -> None:
        """Triangles ``t`` of the points ``p3``, turned so their normal points along
        ``outward``."""
        tri = p3[t]
        nrm = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
        flip = nrm @ np.asarray(outward, dtype=float) < 0
        tri[flip] = tri[flip][:, [0, 2, 1]]
        tris.append(tri)

    def lift(q, axis: int, value: float) -> np.ndarray:
        """2D points of the plane ``axis = value`` (its other two coordinates in order)."""
        p = np.empty((len(q), 3))
        other = [a for a in range(3) if a != axis]
        p[:, other[0]], p[:, other[1]], p[:, axis] = q[:, 0], q[:, 1], value
        return p

    # the two L-shaped ends (y = 0, y = w): the L as two convex pieces sharing no new points
    ell = np.array([[0, 0], [fx, 0], [fx, fz], [wx, fz], [wx, wz], [0, wz]], dtype=float)
    ell_t = np.array([[0, 1, 2], [0, 2, 3], [0, 3, 4], [0, 4, 5]])
    for y, out in ((0.0, (0, -1, 0)), (w, (0, 1, 0))):
        p = np.column_stack([ell[:, 0], np.full(6, y), ell[:, 1]])
        add(p, ell_t, out)
    # planar faces (axis, value, corners in the plane's (u, v), hole centre, outward)
    faces = [
        (2, 0.0, [(0, 0), (fx, 0), (fx, w), (0, w)], FOOT_HOLE, (0, 0, -1)),      # foot bottom
        (2, fz, [(wx, 0), (fx, 0), (fx, w), (wx, w)], FOOT_HOLE, (0, 0, 1)),      # foot top
        (0, fx, [(0, 0), (w, 0), (w, fz), (0, fz)], None, (1, 0, 0)),             # foot end
        (0, 0.0, [(0, 0), (w, 0), (w, wz), (0, wz)], WEB_HOLE, (-1, 0, 0)),       # web back
        (0, wx, [(0, fz), (w, fz), (w, wz), (0, wz)], WEB_HOLE, (1, 0, 0)),       # web front
        (2, wz, [(0, 0), (wx, 0), (wx, w), (0, w)], None, (0, 0, 1)),             # web top
    ]
    for axis, value, corners, hole, out in faces:
        q, t = _plane_face(corners, hole, n)
        add(lift(q, axis, value), t, out)
    # the bore walls: bands between the hole's two rings, normals towards the bore's axis
    for axis, (c0, c1), span in ((2, FOOT_HOLE, (0.0, fz)), (0, WEB_HOLE, (0.0, wx))):
        ring = _circle((c0, c1), n)
        a, b = lift(ring, axis, span[0]), lift(ring, axis, span[1])
        p = np.concatenate([a, b])
        i = np.arange(n)
        j = (i + 1) % n
        t = np.concatenate([np.column_stack([i, j, n + j]), np.column_stack([i, n + j, n + i])])
        tri = p[t]
        nrm = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
        centre = lift(np.array([[c0, c1]]), axis, 0.0)[0]
        radial = tri.mean(axis=1) - centre
        radial[:, axis] = 0.0
        flip = np.einsum("ij,ij->i", nrm, radial) > 0  # outward of the solid: into the bore
        tri[flip] = tri[flip][:, [0, 2, 1]]
        tris.append(tri)
    allt = np.concatenate(tris)
    pts, inv = np.unique(allt.reshape(-1, 3).astype(np.float32), axis=0, return_inverse=True)
    return pts.astype(np.float64), inv.reshape(-1, 3)


def write_stl(path: Path, points: np.ndarray, triangles: np.ndarray) -> None:
    """Binary STL (facet normals from the float32 corners)."""
    tri = points[triangles].astype(np.float32)
    nrm = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]).astype(np.float64)
    nrm /= np.linalg.norm(nrm, axis=1)[:, None]
    out = [HEADER.ljust(80, b" "), struct.pack("<I", len(tri))]
    for n, t in zip(nrm.astype(np.float32), tri):
        out.append(struct.pack("<12fH", *n, *t.ravel(), 0))
    path.write_bytes(b"".join(out))


def main(argv=None) -> int:
    here = Path(__file__).resolve().parent
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--out", type=Path, default=here / "l_bracket.stl",
                   help="file (default: l_bracket.stl in this folder)")
    p.add_argument("--segments", type=int, default=48, help="points per hole (default: 48)")
    a = p.parse_args(argv)
    pts, tri = bracket_surface(a.segments)
    write_stl(a.out, pts, tri)
    print(f"wrote {a.out} ({len(tri)} triangles)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
