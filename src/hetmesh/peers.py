"""Peer meshers for comparisons: Gmsh and Triangle fed hetmesh's material size field.

Neither is a dependency of hetmesh (Gmsh is GPL, Triangle is not free for commercial use):
both come from the optional extra ``pip install "hetmesh[peers]"`` and are imported only when
a peer is run. :func:`available` says which are installed.

A peer meets a threshold the way a user of that tool would: it is given the isotropic size
field of Eqs. (4)-(7),

    h(x) = min(h_max, s * delta_0 / |grad f(x)|),      h_max = domain diameter / 8

(the size hetmesh itself aims for, with hetmesh's default largest size), sampled on a grid and
graded so that it grows by at most 0.3 per unit length (:class:`SizeField`; without grading,
elements where |grad f| ~ 0 next to fast change keep the size h_max whatever ``s``), and the
scale ``s`` is searched (:func:`search`): starting at ``S_START`` it is lowered by the factor
``S_FACTOR`` until the mesh's delta_max < delta_0 (raised while it already holds), then the
last step is bisected, so the peer's mesh is the coarsest on that grid that meets the
threshold. delta is
evaluated exactly as for hetmesh's meshes (:func:`hetmesh.mesh_statistics`: vertex
compositions, every element in its own subregion for feature-tree models). Both peers mesh the
domain *as hetmesh meshed it* (``result.model``: material discontinuities embedded as
interface curves), so no peer element straddles a discontinuity.

- **Gmsh** (:func:`gmsh_mesh`): Frontal-Delaunay (``Mesh.Algorithm = 6``), one thread, the
  true geometry (lines and circular arcs, interfaces embedded), sizes only from the background
  field: by default a ``PostView`` of ``h`` on a regular grid (``field="grid"``); a Python
  callback ``size(x, y)`` (``"callback"``) or a MathEval formula (``"matheval"``) also work.
  The default size field is capped along circular arcs at hetmesh's chord tolerance
  (``chord_tol``, 1e-3 of the diameter; ``None`` turns the cap off), so the peer's curved
  boundaries are as accurate as hetmesh's: without it Gmsh samples a small hole with a
  handful of chords at coarse thresholds (plate_with_holes at 0.2: 198 elements against 640
  with the cap, its holes squares).
- **Gmsh in 3-D** (:func:`search3d`, :func:`gmsh_mesh3d`): an extruded model's section (as
  hetmesh meshes it) extruded by Gmsh, the discontinuities as embedded surfaces, Delaunay
  (``Mesh.Algorithm3D = 1``), the section's graded size field constant along the axis (a
  view of hexahedra), ``s`` searched as in 2-D.
- **Triangle** (:func:`triangle_mesh`): the PSLG of the domain sampled with the same size
  field, a constrained quality Delaunay mesh (``-q`` with hetmesh's 30 degree minimum angle),
  then refinement with a per-triangle maximum area (``-ra``), the area of the equilateral
  triangle of side ``h`` at the centroid, repeated until every triangle obeys it.

Examples
--------
>>> import hetmesh
>>> from hetmesh import peers
>>> model = hetmesh.load_model(hetmesh.example_path("power_plate"))  # doctest: +SKIP
>>> r = peers.search("gmsh", model, 0.05)                              # doctest: +SKIP
>>> r.stats.delta_max < 0.05, r.s                                      # doctest: +SKIP
(True, 0.7...)
"""

from __future__ import annotations

import logging
import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from .density import background_points, gradient_norm, size_at
from .errors import HetmeshError, MeshingError, OptionError
from .metrics import MeshStats, signed_area2
from .options import DEFAULT_CHORD_TOL
from .topology import unique
from .tri.grading import graded

__all__ = ["PEERS", "PeerMesh", "PeerResult", "PeerUnavailable", "available", "size_field",
           "gmsh_mesh", "triangle_mesh", "peer_statistics", "search",
           "S_START", "S_FACTOR", "S_TRIES", "S_BISECT", "SizeField", "PeerMesh3D",
           "gmsh_mesh3d", "peer_statistics3d", "search3d"]

log = logging.getLogger(__name__)

S_START, S_FACTOR, S_TRIES = 1.2, 0.9, 40
S_BISECT = 2                # bisections of the last step of the search
GMSH_ALGORITHM = 6          # Frontal-Delaunay
MIN_ANGLE = 30.0            # Triangle's -q, hetmesh's default floor
GRADATION = 0.3             # size growth per unit length (Lipschitz limit)
GRID_CELLS = 400            # size grid resolution along the longer side
GRID_CELLS_3D = 120         # the same for the 3-D peer (Gmsh looks sizes up in hexahedra)


class PeerUnavailable(HetmeshError):
    """The peer mesher is not installed (``pip install "hetmesh[peers]"``)."""


@dataclass(frozen=True)
class PeerMesh:
    """A peer's triangulation: ``points (N, 2)``, ``triangles (M, 3)`` (only used nodes)
    and the wall time of building and meshing, in seconds."""

    points: np.ndarray
    triangles: np.ndarray
    seconds: float


@dataclass(frozen=True)
class PeerResult:
    """The outcome of :func:`search`: the accepted scale ``s``, its mesh and statistics,
    the wall time of that one meshing run (``seconds``), of the whole search
    (``search_seconds``), and every try (``trace``: dicts with s, elements, delta_max)."""

    peer: str
    threshold: float
    s: float
    mesh: PeerMesh
    stats: MeshStats
    seconds: float
    search_seconds: float
    trace: list = field(default_factory=list)


def available() -> dict[str, str | None]:
    """``{"gmsh": version or None, "triangle": version or None}`` (None: not installed)."""
    out: dict[str, str | None] = {}
    for name in PEERS:
        try:
            mod = __import__(name)
        except Exception:  # ImportError, or a broken shared library
            out[name] = None
            continue
        out[name] = str(getattr(mod, "__version__", None) or _dist_version(name) or "installed")
    return out


def _dist_version(name: str) -> str | None:
    try:
        from importlib.metadata import version

        return version(name)
    except Exception:
        return None


def _require(name: str):
    try:
        return __import__(name)
    except Exception as exc:
        raise PeerUnavailable(f"peer {name!r} is not installed (pip install \"hetmesh[peers]\"): "
                              f"{exc}") from None


# ----------------------------------------------------------------------------- size field
class SizeField:
    """The peers' size field on a regular grid, graded; call it on ``(N, 2)`` points.

    ``h0 = min(h_max, s * threshold / |grad f|)`` (Eqs. 4-7) is evaluated at the nodes of a
    regular grid covering the domain (``cells`` cells along its longer side; nodes outside the
    domain take the value of the nearest node inside), then limited to grow by at most
    ``gradation`` per unit length, ``h(x) = min_y h0(y) + gradation |x - y|_1`` (a Lipschitz
    limit in the L1 distance, exact and fast on a grid; 0.3 is about MMG's ``hgrad = 1.3``):
    without it a peer's elements where the material is flat (|grad f| ~ 0 next to the outer
    surface of the blade) keep the size ``h_max`` up to where the material changes fast, and
    no ``s`` fixes them. Values between nodes are
    interpolated bilinearly. ``grid`` holds ``(X, Y, H)``.
    """

    def __init__(self, model, threshold: float, s: float = 1.0, *, h_max: float | None = None,
                 gradation: float | None = GRADATION, cells: int = GRID_CELLS,
                 gradient_grid: tuple | None = None,
                 chord_tol: float | None = DEFAULT_CHORD_TOL):
        if not (threshold > 0 and s > 0):
            raise OptionError(f"size field needs threshold > 0 and s > 0, got {threshold!r}, {s!r}")
        cap = float(h_max) if h_max is not None else model.domain.diameter / 8.0
        X, Y, G = gradient_grid if gradient_grid is not None else gradient_grid_of(model, cells)
        H = size_at(G, threshold, cap, s)
        if chord_tol is not None:
            H = _chord_capped(H, X, Y, model.domain, chord_tol * model.domain.diameter)
        if gradation:
            H = graded(H, float(X[0, 1] - X[0, 0]), float(gradation))
        self.grid = (X, Y, H)
        from scipy.interpolate import RegularGridInterpolator

        self._interp = RegularGridInterpolator((Y[:, 0], X[0]), H, bounds_error=False,
                                               fill_value=None)

    def __call__(self, points: np.ndarray) -> np.ndarray:
        p = np.asarray(points, float).reshape(-1, 2)
        return self._interp(p[:, ::-1])


def _chord_capped(H: np.ndarray, X: np.ndarray, Y: np.ndarray, domain, tol: float) -> np.ndarray:
    """``H`` capped near every circular arc at the longest chord whose sagitta is ``tol``.

    hetmesh keeps every chord of a curved boundary or interface within its chord tolerance
    (``chord_tol``, 1e-3 of the diameter by default); a peer fed only the material's size
    field would sample a small hole with a handful of chords (a square for a circle) and be
    compared on a coarser geometry. Grid nodes within two cells of an arc take the cap, so
    the interpolated size along the arc does too; the gradation then grades it away."""
    steps = domain.curve_batch.max_step(tol)
    if not np.isfinite(steps).any():
        return H
    pts = np.column_stack([X.ravel(), Y.ravel()])
    band = 2.0 * math.hypot(float(X[0, 1] - X[0, 0]), float(Y[1, 0] - Y[0, 0]))
    out = H.ravel().copy()
    for ci, step in zip(domain.curves, steps):
        if np.isfinite(step):
            near = ci.curve.distance(pts) <= band
            out[near] = np.minimum(out[near], step)
    return out.reshape(H.shape)


def size_field(model, threshold: float, s: float = 1.0, **options) -> SizeField:
    """The peers' :class:`SizeField` (graded, on a grid) for ``model`` at ``threshold``.

    >>> h = size_field(model, 0.05, 0.8)       # doctest: +SKIP
    >>> h(np.array([[1.0, 2.0]]))              # doctest: +SKIP
    """
    return SizeField(model, threshold, s, **options)


def gradient_grid_of(model, cells: int = GRID_CELLS):
    """``(X, Y, G)``: |grad f| (Eq. 5) on the size field's grid (see :func:`_grid_sizes`);
    computed once per model, shared by every scale ``s`` of a search."""
    return _grid_sizes(model.domain, lambda p: gradient_norm(model.material, p), cells)


def _grid_sizes(domain, size: Callable, cells: int):
    """``size`` on a regular grid covering ``domain`` (``cells`` along the longer side);
    nodes outside the domain take the value of the nearest node inside (the material need
    not be defined outside). Returns ``(X, Y, H)`` as 2-D arrays."""
    from scipy.spatial import cKDTree

    x0, y0, x1, y1 = domain.bounds
    pad = 1e-3 * domain.diameter
    x0, y0, x1, y1 = x0 - pad, y0 - pad, x1 + pad, y1 + pad
    step = max(x1 - x0, y1 - y0) / cells
    nx, ny = int(math.ceil((x1 - x0) / step)) + 1, int(math.ceil((y1 - y0) / step)) + 1
    X, Y = np.meshgrid(x0 + step * np.arange(nx), y0 + step * np.arange(ny))
    pts = np.column_stack([X.ravel(), Y.ravel()])
    inside = domain.contains(pts)
    if inside.sum() < 16:  # a domain thinner than the grid: evaluate at its own samples
        inner = background_points(domain, 4 * cells)
        _, j = cKDTree(inner).query(pts)
        return X, Y, size(inner)[j].reshape(X.shape)
    H = np.empty(len(pts))
    H[inside] = size(pts[inside])
    if (~inside).any():
        _, j = cKDTree(pts[inside]).query(pts[~inside])
        H[~inside] = H[inside][j]
    return X, Y, H.reshape(X.shape)


# ----------------------------------------------------------------------------- Gmsh
def _gmsh_geometry(gmsh, domain) -> tuple[int, list[int]]:
    """Add the domain to gmsh's built-in kernel; returns (surface tag, embedded curve tags)."""
    geo = gmsh.model.geo
    tol = 1e-9 * domain.diameter
    points: dict[tuple[int, int], int] = {}

    def point(p) -> int:
        key = (int(round(p[0] / tol)), int(round(p[1] / tol)))
        if key not in points:
            points[key] = geo.addPoint(float(p[0]), float(p[1]), 0.0)
        return points[key]

    def curve_tags(curve) -> list[int]:
        if not hasattr(curve, "radius"):  # a segment
            return [geo.addLine(point(curve.start), point(curve.end))]
        n = max(1, int(math.ceil(abs(curve.sweep) / (0.9 * math.pi))))  # gmsh arcs < pi
        t = np.linspace(0.0, 1.0, n + 1)
        ends = curve.point(t)
        c = geo.addPoint(curve.center[0], curve.center[1], 0.0)  # not part of the mesh
        return [geo.addCircleArc(point(ends[i]), c, point(ends[i + 1])) for i in range(n)]

    def loop(chain) -> int:
        return geo.addCurveLoop([t for c in chain.curves for t in curve_tags(c)])

    loops = [loop(domain.outer)] + [loop(h) for h in domain.holes]
    surface = geo.addPlaneSurface(loops)
    embedded = [t for path in domain.interfaces for c in path.curves for t in curve_tags(c)]
    return surface, embedded


def gmsh_mesh(domain, size, *, field: str = "grid", cells: int = GRID_CELLS,
              h_max: float | None = None,
              threads: int = 1, algorithm: int = GMSH_ALGORITHM) -> PeerMesh:
    """Mesh ``domain`` with Gmsh, element sizes only from a background field.

    Parameters
    ----------
    domain : Domain
        Outer loop and holes become a plane surface; interface curves are embedded in it.
    size
        ``field="grid"``: a vectorised callable ``(N, 2) -> (N,)``, sampled on a regular grid
        of ``cells`` cells along the longer side and given to Gmsh as a ``PostView`` field;
        ``"callback"``: a scalar callable ``size(x, y) -> float`` (Gmsh's size callback);
        ``"matheval"``: a formula in ``x``, ``y`` for Gmsh's MathEval field.
    h_max : float, optional
        ``Mesh.MeshSizeMax`` (default: none).
    threads, algorithm : int
        ``General.NumThreads`` and ``Mesh.Algorithm`` (6 = Frontal-Delaunay).

    Returns
    -------
    PeerMesh
        The nodes used by triangles, the triangles, and the wall time of geometry, field,
        ``generate(2)`` and reading back.
    """
    gmsh = _require("gmsh")
    if field not in ("grid", "callback", "matheval"):
        raise OptionError(f"gmsh size field must be 'grid', 'callback' or 'matheval', "
                          f"got {field!r}")
    t0 = time.perf_counter()
    gmsh.initialize(readConfigFiles=False, interruptible=False)
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        gmsh.option.setNumber("General.NumThreads", threads)
        gmsh.model.add("hetmesh_peer")
        surface, embedded = _gmsh_geometry(gmsh, domain)
        gmsh.model.geo.synchronize()
        if embedded:
            gmsh.model.mesh.embed(1, embedded, 2, surface)
        for k in ("MeshSizeExtendFromBoundary", "MeshSizeFromPoints", "MeshSizeFromCurvature"):
            gmsh.option.setNumber(f"Mesh.{k}", 0)
        gmsh.option.setNumber("Mesh.Algorithm", algorithm)
        if h_max is not None:
            gmsh.option.setNumber("Mesh.MeshSizeMax", float(h_max))
        if field == "grid":
            _gmsh_grid_field(gmsh, domain, size, cells)
        elif field == "callback":
            gmsh.model.mesh.setSizeCallback(lambda dim, tag, x, y, z, lc: float(size(x, y)))
        else:
            f = gmsh.model.mesh.field.add("MathEval")
            gmsh.model.mesh.field.setString(f, "F", str(size))
            gmsh.model.mesh.field.setAsBackgroundMesh(f)
        gmsh.model.mesh.generate(2)
        tags, xyz, _ = gmsh.model.mesh.getNodes()
        _, enodes = gmsh.model.mesh.getElementsByType(2)
    except Exception as exc:
        if isinstance(exc, HetmeshError):
            raise
        raise MeshingError(f"gmsh failed: {exc}") from exc
    finally:
        gmsh.finalize()
    seconds = time.perf_counter() - t0
    tris = _cells_by_index(tags, enodes, 3)
    pts, tris = _compact(xyz.reshape(-1, 3)[:, :2], tris)
    return PeerMesh(pts, tris, seconds)


def _cells_by_index(tags: np.ndarray, enodes: np.ndarray, k: int) -> np.ndarray:
    """Gmsh's element node tags ``enodes`` as ``(M, k)`` indices into its node list, whose
    node tags are ``tags`` (as ``gmsh.model.mesh.getNodes`` returns them)."""
    tags = tags.astype(np.int64)
    index = np.full(int(tags.max()) + 1, -1, dtype=np.int64)
    index[tags] = np.arange(len(tags))
    return index[enodes.astype(np.int64)].reshape(-1, k)


def _gmsh_grid_field(gmsh, domain, size, cells: int) -> None:
    """``size`` on a grid as a list-based view of scalar triangles, the background field."""
    X, Y, H = size.grid if hasattr(size, "grid") else _grid_sizes(domain, size, cells)
    ny, nx = X.shape
    idx = np.arange(nx * ny).reshape(ny, nx)
    a, b = idx[:-1, :-1].ravel(), idx[:-1, 1:].ravel()
    c, d = idx[1:, 1:].ravel(), idx[1:, :-1].ravel()
    tri = np.concatenate([np.column_stack([a, b, c]), np.column_stack([a, c, d])])
    x, y, h = X.ravel(), Y.ravel(), H.ravel()
    data = np.column_stack([x[tri], y[tri], np.zeros(tri.shape), h[tri]])  # ST layout
    view = gmsh.view.add("hetmesh size")
    gmsh.view.addListData(view, "ST", len(tri), data.ravel().tolist())
    f = gmsh.model.mesh.field.add("PostView")
    gmsh.model.mesh.field.setNumber(f, "ViewTag", view)
    gmsh.model.mesh.field.setAsBackgroundMesh(f)


def _compact(points: np.ndarray, triangles: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Drop the nodes no triangle uses (Gmsh meshes arc centres as 0-d entities)."""
    used = unique(triangles)
    remap = np.full(len(points), -1, np.int64)
    remap[used] = np.arange(len(used))
    return np.ascontiguousarray(points[used], float), remap[triangles].astype(np.int32)


# ----------------------------------------------------------------------------- Triangle
def _hole_points(domain) -> np.ndarray:
    """A point strictly inside every hole (Triangle eats the triangles around it)."""
    import shapely

    out = []
    for hole in domain.holes:
        ring = np.vstack([c.point(np.linspace(0.0, 1.0, 65))[:-1] for c in hole.curves])
        out.append(np.asarray(shapely.Polygon(ring).representative_point().coords[0]))
    return np.asarray(out, float).reshape(-1, 2)


def triangle_mesh(domain, size: Callable[[np.ndarray], np.ndarray], *,
                  min_angle: float = MIN_ANGLE, chord_tol: float | None = None,
                  max_rounds: int = 30) -> PeerMesh:
    """Mesh ``domain`` with Shewchuk's Triangle following the size field ``size``.

    The curves (interfaces included) are sampled with ``size`` into a PSLG
    (:func:`hetmesh.tri.geometry.build_pslg`, chord tolerance 1e-3 x diameter by default), meshed
    with ``-pq<min_angle>``, then refined with ``-rpq<min_angle>a`` and a per-triangle area
    bound ``sqrt(3)/4 h(centroid)^2`` until every triangle obeys its bound.

    Returns
    -------
    PeerMesh
    """
    triangle = _require("triangle")
    from .tri.geometry import build_pslg

    t0 = time.perf_counter()
    pslg = build_pslg(domain, size, chord_tol)
    data = {"vertices": np.array(pslg.vertices, float),
            "segments": np.array(pslg.edges, np.int32)}
    holes = _hole_points(domain)
    if len(holes):
        data["holes"] = holes
    q = f"q{min_angle:g}"
    mesh = triangle.triangulate(data, f"p{q}Q")
    for _ in range(max_rounds):
        P, T = mesh["vertices"], mesh["triangles"]
        area = 0.5 * np.abs(signed_area2(P[T[:, 0]], P[T[:, 1]], P[T[:, 2]]))
        bound = math.sqrt(3.0) / 4.0 * size(P[T].mean(axis=1)) ** 2
        if (area <= bound * (1.0 + 1e-9)).all():
            break
        mesh = dict(mesh, triangle_max_area=bound.reshape(-1, 1))
        if len(holes):
            mesh["holes"] = holes
        mesh = triangle.triangulate(mesh, f"rp{q}aQ")
    else:
        log.warning("triangle: area bounds still violated after %d refinement rounds", max_rounds)
    pts, tris = _compact(np.asarray(mesh["vertices"], float), np.asarray(mesh["triangles"]))
    return PeerMesh(pts, tris, time.perf_counter() - t0)


PEERS: dict[str, Callable[..., PeerMesh]] = {"gmsh": gmsh_mesh, "triangle": triangle_mesh}


# ----------------------------------------------------------------------------- search
def peer_statistics(model, mesh: PeerMesh) -> MeshStats:
    """Np, Ne, q and delta of a peer mesh, evaluated like hetmesh's own
    (:func:`hetmesh.mesh_statistics`)."""
    from .kernel import mesh_statistics
    from .mesh import Mesh

    return mesh_statistics(Mesh(mesh.points, mesh.triangles), model)


def search(peer: str, model, threshold: float, *, s_start: float = S_START,
           factor: float = S_FACTOR, tries: int = S_TRIES, bisect: int = S_BISECT,
           h_max: float | None = None, gradation: float | None = GRADATION,
           size: Callable[[float], object] | None = None, **options) -> PeerResult:
    """The coarsest mesh of ``peer`` with delta_max < ``threshold`` over the scale ``s``.

    ``s`` starts at ``s_start`` and is multiplied by ``factor`` until the threshold is met
    (divided by it while it is met already, to find where it stops being met); then the last
    interval between a failing and a passing ``s`` is bisected ``bisect`` times (geometric
    mid-points). Returns the largest passing ``s`` found.

    Parameters
    ----------
    peer : {"gmsh", "triangle"}
    model : Model
        The model as it is meshed (``result.model`` of :func:`hetmesh.generate` carries the
        embedded material discontinuities).
    threshold : float
    h_max, gradation : float, optional
        Of the default size field (:class:`SizeField`).
    size : callable ``s -> size``, optional
        Builds the mesher's ``size`` argument for a scale ``s`` instead of the default
        :class:`SizeField` (e.g. an analytic callback with ``field="callback"`` for Gmsh).
    options
        Passed to the peer's mesher (:func:`gmsh_mesh`, :func:`triangle_mesh`).

    Raises
    ------
    PeerUnavailable
        If the peer is not installed.
    MeshingError
        If no ``s`` met the threshold within ``tries`` meshes.
    """
    if peer not in PEERS:
        raise OptionError(f"unknown peer {peer!r} (known: {', '.join(PEERS)})")
    if not (0 < factor < 1):
        raise OptionError(f"factor must be in (0, 1), got {factor!r}")
    mesher = PEERS[peer]
    t0 = time.perf_counter()
    grid = gradient_grid_of(model) if size is None else None

    def build(s: float):
        if size is None:
            sz = size_field(model, threshold, s, h_max=h_max, gradation=gradation,
                            gradient_grid=grid)
        else:
            sz = size(s)
        mesh = mesher(model.domain, sz, **options)
        return mesh, peer_statistics(model, mesh)

    return _scale_search(build, peer, peer, threshold, t0, s_start=s_start, factor=factor,
                         tries=tries, bisect=bisect)


def _scale_search(build, peer: str, label: str, threshold: float, t0: float, *,
                  s_start: float, factor: float, tries: int, bisect: int) -> PeerResult:
    """The search of :func:`search` (and of the 3-D one) over the scale s: ``build(s)`` gives
    a peer's mesh and its statistics; a mesh passes when its delta_max is below
    ``threshold``. ``label`` names the peer in the log and in the error."""
    trace: list[dict] = []
    results: dict[float, tuple] = {}

    def attempt(s: float) -> bool:
        mesh, st = build(s)
        ok = st.delta_max < threshold
        trace.append({"s": s, "elements": st.n_elements, "delta_max": st.delta_max,
                      "seconds": mesh.seconds, "pass": ok})
        log.debug("%s s=%.4f: %d elements, delta_max %.4g", label, s, st.n_elements,
                  st.delta_max)
        if ok:
            results[s] = (mesh, st)
        return ok

    s = s_start
    s_pass, s_fail = (s, None) if attempt(s) else (None, s)
    while len(trace) < tries and (s_pass is None or s_fail is None):
        s = s * factor if s_pass is None else s / factor
        if attempt(s):
            s_pass = s
            if len(trace) >= 2 and trace[-2]["pass"] and \
                    trace[-2]["elements"] == trace[-1]["elements"]:
                break  # coarser scales no longer change the mesh (sizes at h_max everywhere)
        else:
            s_fail = s
    if s_pass is None:
        raise MeshingError(f"{label}: no scale s met delta_max < {threshold:g} in "
                           f"{len(trace)} tries (last s = {s:.3g})")
    for _ in range(bisect if s_fail is not None else 0):
        mid = math.sqrt(s_pass * s_fail)
        if attempt(mid):
            s_pass = mid
        else:
            s_fail = mid
    mesh, st = results[s_pass]
    return PeerResult(peer=peer, threshold=threshold, s=s_pass, mesh=mesh, stats=st,
                      seconds=mesh.seconds, search_seconds=time.perf_counter() - t0, trace=trace)


# ----------------------------------------------------------------------------- 3-D (Gmsh)
@dataclass(frozen=True)
class PeerMesh3D:
    """A peer's tetrahedral mesh: ``points (N, 3)``, ``tets (M, 4)`` (only used nodes) and
    the wall time of building and meshing, in seconds."""

    points: np.ndarray
    tets: np.ndarray
    seconds: float


def _section_model(model):
    """The 2-D model of an extruded 3-D model's section as hetmesh meshes it (material
    discontinuities embedded), or :class:`OptionError` for other solids."""
    from .io.model import Model
    from .tri.discontinuity import embed_discontinuities

    solid = model.solid
    if getattr(model, "material2d", None) is None or not hasattr(solid, "section"):
        raise OptionError(f"the 3-D Gmsh peer meshes extrusions of 2-D models (a composition "
                          f"that does not change along the axis); {model.name!r} is not one")
    return embed_discontinuities(Model(name=model.name, domain=solid.section,
                                       material=model.material2d))


def _gmsh_hex_field(gmsh, size: SizeField, length: float) -> None:
    """The section's graded size grid as a view of scalar hexahedra spanning the extrusion
    (the size does not change along it), the background field."""
    X, Y, H = size.grid
    ny, nx = X.shape
    idx = np.arange(nx * ny).reshape(ny, nx)
    quad = np.column_stack([idx[:-1, :-1].ravel(), idx[:-1, 1:].ravel(),
                            idx[1:, 1:].ravel(), idx[1:, :-1].ravel()])
    x, y, h = X.ravel()[quad], Y.ravel()[quad], H.ravel()[quad]
    z0, z1 = np.full(quad.shape, -0.01 * length), np.full(quad.shape, 1.01 * length)
    data = np.concatenate([np.concatenate([x, x], 1), np.concatenate([y, y], 1),
                           np.concatenate([z0, z1], 1), np.concatenate([h, h], 1)], axis=1)
    view = gmsh.view.add("hetmesh size")
    gmsh.view.addListData(view, "SH", len(quad), data.ravel().tolist())
    f = gmsh.model.mesh.field.add("PostView")
    gmsh.model.mesh.field.setNumber(f, "ViewTag", view)
    gmsh.model.mesh.field.setAsBackgroundMesh(f)


def gmsh_mesh3d(model, size: SizeField, *, section=None, threads: int = 1,
                algorithm3d: int = 1) -> PeerMesh3D:
    """Gmsh's tetrahedral mesh of an extruded model, sizes only from ``size`` (the section's
    :class:`SizeField`, constant along the axis): the section (``section``, default
    :func:`_section_model`'s, with its embedded discontinuity curves) extruded by the solid's
    length, the extruded discontinuities embedded as surfaces, ``generate(3)`` with
    ``Mesh.Algorithm3D`` (1 = Delaunay), one thread."""
    gmsh = _require("gmsh")
    section = section or _section_model(model)
    solid = model.solid
    t0 = time.perf_counter()
    gmsh.initialize(readConfigFiles=False, interruptible=False)
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        gmsh.option.setNumber("General.NumThreads", threads)
        gmsh.model.add("hetmesh_peer3d")
        surface, embedded = _gmsh_geometry(gmsh, section.domain)
        geo = gmsh.model.geo
        out = geo.extrude([(2, surface)], 0, 0, solid.length)
        top = out[0][1]
        volume = [t for d, t in out if d == 3][0]
        walls, tops = [], []
        for c in embedded:
            ext = geo.extrude([(1, c)], 0, 0, solid.length)
            tops.append(ext[0][1])
            walls += [t for d, t in ext if d == 2]
        if walls:  # the walls' top edges and corners are the volume's: one entity each
            geo.removeAllDuplicates()
        geo.synchronize()
        if walls:  # the discontinuities: curves in both caps, walls in the volume
            gmsh.model.mesh.embed(1, embedded, 2, surface)
            gmsh.model.mesh.embed(1, tops, 2, top)
            gmsh.model.mesh.embed(2, walls, 3, volume)
        for k in ("MeshSizeExtendFromBoundary", "MeshSizeFromPoints", "MeshSizeFromCurvature"):
            gmsh.option.setNumber(f"Mesh.{k}", 0)
        gmsh.option.setNumber("Mesh.Algorithm", GMSH_ALGORITHM)
        gmsh.option.setNumber("Mesh.Algorithm3D", algorithm3d)
        _gmsh_hex_field(gmsh, size, solid.length)
        gmsh.model.mesh.generate(3)
        tags, xyz, _ = gmsh.model.mesh.getNodes()
        _, enodes = gmsh.model.mesh.getElementsByType(4)
    except Exception as exc:
        if isinstance(exc, HetmeshError):
            raise
        raise MeshingError(f"gmsh failed: {exc}") from exc
    finally:
        gmsh.finalize()
    seconds = time.perf_counter() - t0
    tets = _cells_by_index(tags, enodes, 4)
    used, inv = unique(tets, return_inverse=True)
    p = xyz.reshape(-1, 3)[used]
    points = solid.to3d(p[:, :2], p[:, 2] + solid.s0)
    return PeerMesh3D(points, inv.reshape(-1, 4), seconds)


def peer_statistics3d(model, mesh: PeerMesh3D) -> MeshStats:
    """Np, Ne, radius ratio, smallest dihedral angle and delta of a tetrahedral peer mesh,
    delta over the vertices as for hetmesh's meshes (each tetrahedron in its own subregion
    for a feature-tree material)."""
    from .material.field import element_subregions, has_subregions
    from .mesh import simplex_measures
    from .metrics import delta_vertices, dihedral_angles, statistics, tet_quality

    P, T = mesh.points, mesh.tets.copy()
    neg = simplex_measures(P, T) < 0
    T[neg] = T[neg][:, [0, 1, 3, 2]]
    field_ = model.material
    if has_subregions(field_):
        sub = element_subregions(field_, P, T)
        c = field_.composition(P[T.ravel()], region=np.repeat(sub, 4)).reshape(len(T), 4, -1)
        delta = (c.max(axis=1) - c.min(axis=1)).max(axis=1)
    else:
        delta = delta_vertices(field_.composition(P), T)
    return statistics(P, T, delta, quality=tet_quality(P, T),
                      angle=dihedral_angles(P, T).min(axis=1))


def search3d(peer: str, model, threshold: float, *, s_start: float = S_START,
             factor: float = S_FACTOR, tries: int = S_TRIES, bisect: int = S_BISECT,
             gradation: float | None = GRADATION, cells: int = GRID_CELLS_3D,
             **options) -> PeerResult:
    """The coarsest Gmsh tetrahedral mesh of an extruded 3-D model with delta_max <
    ``threshold`` over the scale ``s`` of the size field, searched as :func:`search` does
    (the section's graded :class:`SizeField`, whose chord cap keeps the curved faces as
    accurate as hetmesh's, extended along the axis; :func:`gmsh_mesh3d`). Only ``"gmsh"``.

    Raises
    ------
    PeerUnavailable
        If Gmsh is not installed.
    OptionError
        If ``model`` is not an extrusion of a 2-D model.
    MeshingError
        If no ``s`` met the threshold within ``tries`` meshes.
    """
    if peer != "gmsh":
        raise OptionError(f"the 3-D peer is gmsh, got {peer!r}")
    _require("gmsh")
    section = _section_model(model)
    t0 = time.perf_counter()
    grid = gradient_grid_of(section, cells)

    def build(s: float):
        sz = size_field(section, threshold, s, gradation=gradation, gradient_grid=grid,
                        cells=cells)
        mesh = gmsh_mesh3d(model, sz, section=section, **options)
        return mesh, peer_statistics3d(model, mesh)

    return _scale_search(build, peer, "gmsh 3-D", threshold, t0, s_start=s_start,
                         factor=factor, tries=tries, bisect=bisect)
