"""Thermo-mechanical finite element analysis of graded objects (paper Sec. 4.4, case study 4).

Steady heat conduction, then linear thermoelasticity (plane strain or plane stress) with
properties mixed from the composition at the quadrature points, on scikit-fem::

    model = hetmesh.load_model("fgm_plate.toml")        # with an [fea] table
    mesh = hetmesh.generate(model, 0.05).mesh
    result = hetmesh.fea.solve(mesh, model)
    result.probes["P1"]["von_mises"]                   # Pa
    hetmesh.fea.write_report(result, "fea.json")
    hetmesh.fea.plot_von_mises(result, "vm.png")

    s = hetmesh.fea.study(model, quick=True)           # case study 4 (Table 7 analog)
    s.needed                                           # elements for 0.5 % at every probe

On a tetrahedral mesh (``mesh.dim == 3``) the same ``solve`` runs the 3-D analysis (P1/P2
tetrahedra, conditions on named faces, pressures; multigrid-preconditioned CG for large
systems), validated against the exact radial solutions of :mod:`~hetmesh.fea.radial`.

Modules: :mod:`~hetmesh.fea.config` (the ``[fea]`` table; pure numpy, imported by the model
parser), :mod:`~hetmesh.fea.config3d` (its 3-D form), :mod:`~hetmesh.fea.solid` (3-D
assembly and solve on arrays), :mod:`~hetmesh.fea.analysis3d` (the 3-D analysis of a mesh),
:mod:`~hetmesh.fea.linsolve` (direct / AMG-CG), :mod:`~hetmesh.fea.radial` (exact 1-D
references), :mod:`~hetmesh.fea.verification` (structured meshes and the validation cases),
:mod:`~hetmesh.fea.mixing` (rule of mixtures, Mori-Tanaka), :mod:`~hetmesh.fea.analysis`
(assembly, solves, recovery, probes), :mod:`~hetmesh.fea.report` (JSON report, plot),
:mod:`~hetmesh.fea.probe_study` (the case-4 study, :func:`study`; not named ``study`` so that
importing it cannot shadow the function). scikit-fem and matplotlib are imported on first use
of the solver and the plot.
"""

from __future__ import annotations

from .config import FEAConfig, Properties, parse_fea
from .config3d import FEAConfig3D, parse_fea3d
from .mixing import mix, mix_linear, mix_mori_tanaka

__all__ = ["solve", "FEAResult", "FEAResult3D", "FEAConfig", "FEAConfig3D", "Properties",
           "parse_fea", "parse_fea3d", "mix", "mix_linear", "mix_mori_tanaka", "von_mises",
           "write_report", "plot_von_mises", "von_mises_figure", "study", "ProbeStudy",
           "solve_tets"]

_LAZY = {"solve": "analysis", "FEAResult": "analysis", "von_mises": "analysis",
         "FEAResult3D": "analysis3d", "solve_tets": "solid",
         "write_report": "report", "plot_von_mises": "report", "von_mises_figure": "report",
         "study": "probe_study", "ProbeStudy": "probe_study"}


def __getattr__(name: str):
    if name in _LAZY:
        import importlib

        module = importlib.import_module(f"{__name__}.{_LAZY[name]}")
        return getattr(module, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
