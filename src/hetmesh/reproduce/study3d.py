"""The 3-D section of ``hetmesh reproduce``: graded solids, adaptive against uniform tetrahedra.

The paper stops at 2-D; this section runs its comparison on two solids (``--3d``):

- ``fgm_plate_3d``: case study 4's plate extruded 10 mm, in plane strain (u_z = 0 on both
  end faces), whose exact 3-D field is the 2-D plane-strain one at every z: the reference is
  the 2-D model ``fgm_plate`` solved on a fine uniform mesh
  (:func:`hetmesh.fea.probe_study.plane_strain_reference`);
- ``graded_cylinder``: the thick-walled tube under internal pressure, against the exact
  radial solution (:func:`hetmesh.fea.probe_study.radial_reference`).

For each: the adaptive mesh (:func:`hetmesh.generate`) and the uniform baseline
(:func:`hetmesh.uniform`, :mod:`hetmesh.tet.uniform`) at two thresholds, with N_iso3 and the
quality; Gmsh's 3-D mesh with the graded size field as a peer when installed
(:func:`hetmesh.peers.search3d`); and the FEA study
(:func:`hetmesh.fea.probe_study.study3d`): the tetrahedra each family needs for 0.5 % at
the probes; and its third family (:func:`refine_case`): the material-adaptive mesh,
started with a coarser chord tolerance (:data:`REFINE_START_CHORD_TOL`), refined by the
probes' dual-weighted indicator (the plate's narrowed, :data:`PLATE_REFINE_ELEMENT_FACTOR`)
bisecting the edges along which the stress varies, with the uniform family measured again
at that chord tolerance for a like-for-like ratio.
:func:`hetmesh.reproduce.report.render3d` renders the records.
"""

from __future__ import annotations

import logging
import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field

from ..errors import HetmeshError

__all__ = ["Case3D", "CASES3D", "MeshRun3D", "Section3D", "run3d", "CHORD_TOL",
           "REFINE_START_CHORD_TOL", "SAME_CHORD_UNIFORM_MAX", "PLATE_REFINE_ELEMENT_FACTOR"]

log = logging.getLogger(__name__)

#: the chord tolerance (x the solid's diameter) of the FEA study's meshes, both families:
#: with the meshers' default 0.002 the polygonal inner face of the graded cylinder alone
#: keeps the stresses at R1..R3 about 0.5 % off (docs/fea.md, "3-D study")
CHORD_TOL = 2e-4
#: the chord tolerance of the refined family's starting mesh (x the diameter): coarser than
#: the other families', as the refinement puts every new boundary vertex on the exact
#: surface; at CHORD_TOL the graded cylinder's starting mesh alone has 3,129 tetrahedra, more
#: than half the uniform family's count (docs/fea.md, "The 3-D study with a third family")
REFINE_START_CHORD_TOL = 1e-3
#: the plate's goal functional: its mollifier is at least a quarter of the probe element's
#: longest edge, not the whole edge: the plate's swept tetrahedra are long, and with the
#: whole edge the mollifier spans 1.4-3.8 mm about the Q probes and the marks fall 2-6 mm
#: from them (docs/fea.md, "The 3-D study with a third family"). Its start is the
#: cylinder's, :data:`REFINE_START_CHORD_TOL` (since the refinement bisects the edges along
#: which the stress varies, :func:`hetmesh.fea.adapt.stress_metric`; before, 2e-3)
PLATE_REFINE_ELEMENT_FACTOR = 0.25
#: the uniform family measured again at the refined family's start chord tolerance (the
#: like-for-like ratio of the refined family): the plan's counts up to this many tetrahedra
SAME_CHORD_UNIFORM_MAX = 25_000


@dataclass(frozen=True)
class Case3D:
    """A solid of the 3-D section: the example, its thresholds (full and quick), and the
    study's reference (``"radial"`` or ``"plane-strain"`` from the 2-D example
    ``model2d``)."""

    name: str
    title: str
    thresholds: tuple[float, ...]
    quick: tuple[float, ...]
    reference: str
    model2d: str | None = None
    #: the chord tolerance (x the diameter) of the refined family's start
    refine_start_chord: float = REFINE_START_CHORD_TOL
    #: the refined family's goal functional: its mollifier's floor, this times the longest
    #: edge of the probe's element (None: :data:`hetmesh.fea.goal.DEFAULT_ELEMENT_FACTOR`)
    refine_element_factor: float | None = None


CASES3D = {c.name: c for c in (
    Case3D("fgm_plate_3d", "case study 4 extruded 10 mm, plane strain", (0.3, 0.2), (0.3,),
           "plane-strain", "fgm_plate", refine_element_factor=PLATE_REFINE_ELEMENT_FACTOR),
    Case3D("graded_cylinder", "graded tube under 100 MPa internal pressure", (0.2, 0.1),
           (0.2,), "radial"),
)}


@dataclass
class MeshRun3D:
    """One solid at one threshold: adaptive, uniform and peer tetrahedra and figures."""

    case: str
    threshold: float
    n_iso3: float = math.nan
    adaptive: dict | None = None
    uniform: dict | None = None
    peers: dict = field(default_factory=dict)
    error: str | None = None

    @property
    def ratio(self) -> float:
        if not self.adaptive or not self.uniform:
            return math.nan
        return self.adaptive["elements"] / self.uniform["elements"]


@dataclass
class Section3D:
    """What the 3-D section measured: mesh runs, FEA studies (name -> ProbeStudy or None)
    and their errors (name -> message)."""

    quick: bool
    runs: list[MeshRun3D] = field(default_factory=list)
    studies: dict = field(default_factory=dict)
    study_errors: dict = field(default_factory=dict)
    seconds: float = math.nan
    #: name -> :func:`hetmesh.fea.adapt.refinement_study` (the material-adaptive mesh refined
    #: by the solution: the study's third family), or {"error": message}
    refinements: dict = field(default_factory=dict)


def _figures(result, seconds: float) -> dict:
    from ..metrics import dihedral_angles, tet_quality

    mesh = result.mesh
    ang = dihedral_angles(mesh.points, mesh.cells).min(axis=1)
    q = tet_quality(mesh.points, mesh.cells)
    import numpy as np

    return {"elements": int(mesh.n_elements), "points": int(len(mesh.points)),
            "delta_max": float(result.stats.delta_max),
            "delta_avg": float(result.stats.delta_avg),
            "dihedral_min": float(ang.min()), "dihedral_p1": float(np.percentile(ang, 1)),
            "radius_ratio_mean": float(q.mean()), "seconds": float(seconds)}


def mesh_run3d(case: Case3D, threshold: float, model, peers: list[str]) -> MeshRun3D:
    """Adaptive and uniform meshes (and the peers') of one solid at one threshold."""
    from .. import peers as peer_module
    from ..meshing import generate, uniform
    from ..tet.mesher import n_iso3

    run = MeshRun3D(case.name, threshold)
    try:
        run.n_iso3 = float(n_iso3(model.solid, model.material, threshold))
        t0 = time.perf_counter()
        a = generate(model, threshold)
        run.adaptive = _figures(a, time.perf_counter() - t0)
        t0 = time.perf_counter()
        u = uniform(model, threshold)
        run.uniform = _figures(u, time.perf_counter() - t0)
        run.uniform["size"] = float(u.options["size"])
    except HetmeshError as exc:
        run.error = str(exc).splitlines()[0]
        log.warning("%s at delta_0 = %g: %s", case.name, threshold, run.error)
        return run
    for peer in peers:
        try:
            r = peer_module.search3d(peer, model, threshold)
            run.peers[peer] = {"elements": int(r.stats.n_elements),
                               "delta_max": float(r.stats.delta_max), "s": float(r.s),
                               "seconds": float(r.seconds),
                               "search_seconds": float(r.search_seconds),
                               "dihedral_min": float(r.stats.angle_min)}
        except HetmeshError as exc:
            run.peers[peer] = {"error": str(exc).splitlines()[0]}
    return run


def study_case(case: Case3D, model, quick: bool, progress=None, **plan):
    """The FEA study of one solid (:func:`hetmesh.fea.probe_study.study3d`; ``plan``:
    ``uniform_elements``, ``thresholds`` instead of the plan's)."""
    from ..fea import probe_study as ps
    from ..io.model import example_path, load_model

    if case.reference == "radial":
        ref = ps.radial_reference(model)
    else:
        elements = ps.PLANS3D["quick" if quick else "full"].reference_elements
        ref = ps.plane_strain_reference(model, load_model(example_path(case.model2d)),
                                        elements=elements)
    return ps.study3d(model, ref, quick=quick, progress=progress, chord_tol=CHORD_TOL, **plan)


def refine_case(case: Case3D, model, study, quick: bool, plan: dict,
                steps: int | None = None) -> dict | None:
    """The study's third family (:func:`hetmesh.fea.adapt.refinement_study`) from the
    material-adaptive mesh at the plan's largest threshold and the case's start chord
    tolerance (default :data:`REFINE_START_CHORD_TOL`), with the case's mollifier factor,
    and the uniform family again at that chord tolerance (the plan's
    counts up to :data:`SAME_CHORD_UNIFORM_MAX`); ``steps`` refinements instead of the
    plan's; ``{"error": message}`` if it fails, None if the plan has no threshold."""
    from ..fea import probe_study as ps
    from ..fea.adapt import refinement_study

    d0s = plan.get("thresholds", ps.PLANS3D["quick" if quick else "full"].thresholds)
    if not d0s:
        return None
    counts = plan.get("uniform_elements",
                      ps.PLANS3D["quick" if quick else "full"].uniform_elements)
    try:
        return refinement_study(model, study.reference, study, threshold=max(d0s),
                                quick=quick, chord_tol=CHORD_TOL,
                                start_chord_tol=case.refine_start_chord,
                                goal_element_factor=case.refine_element_factor,
                                steps=steps,
                                uniform_elements=[n for n in counts
                                                  if n <= SAME_CHORD_UNIFORM_MAX])
    except HetmeshError as exc:
        log.warning("3-D refinement of %s failed: %s", model.name, exc)
        return {"error": str(exc).splitlines()[0]}


def run3d(*, quick: bool = False, peers: list[str] | None = None, study: bool = True,
          cases: list[str] | None = None, meshes: bool = True,
          progress: Callable[[str, float | None], None] | None = None,
          refine: bool = True, **plan) -> Section3D:
    """Everything the 3-D section measures (see the module docstring); failures are
    recorded with their message, not raised. ``meshes=False`` skips the mesh table;
    ``plan`` (``uniform_elements``, ``thresholds``) overrides the FEA study's plan;
    ``refine`` adds the study's third family (:func:`refine_case`)."""
    from ..io.model import example_path, load_model

    t0 = time.perf_counter()
    names = list(CASES3D) if cases is None else list(cases)
    out = Section3D(quick=quick)
    pairs = [(CASES3D[n], t) for n in names
             for t in (CASES3D[n].quick if quick else CASES3D[n].thresholds)] if meshes else []
    steps = len(pairs) + (len(names) if study else 0)
    done = 0
    models = {n: load_model(example_path(n)) for n in names}
    for case, t in pairs:
        if progress is not None:
            progress(f"3-D {case.name} delta_0={t:g}: adaptive, uniform, peers", done / steps)
        out.runs.append(mesh_run3d(case, t, models[case.name], list(peers or [])))
        done += 1
    if study:
        for n in names:
            base = done

            def sub(stage, fraction, n=n, base=base):
                if progress is not None:
                    progress(f"3-D FEA study {n}: {stage}", (base + (fraction or 0)) / steps)

            try:
                out.studies[n] = study_case(CASES3D[n], models[n], quick, sub, **plan)
            except HetmeshError as exc:
                out.study_errors[n] = str(exc).splitlines()[0]
                log.warning("3-D study of %s failed: %s", n, out.study_errors[n])
            if refine and n in out.studies:
                sub("material-adaptive + solution-adaptive refinement", 0.95)
                r = refine_case(CASES3D[n], models[n], out.studies[n], quick, plan)
                if r is not None:
                    out.refinements[n] = r
            done += 1
    out.seconds = time.perf_counter() - t0
    return out
