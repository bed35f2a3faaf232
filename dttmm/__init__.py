"""dttmm — planar and spatial manipulators with flexible links by the discrete time transfer
matrix method. ``load_case`` reads either kind of case file; ``simulate``, ``accelerations`` and
``statics`` take either kind of case (a planar arm runs on the planar kernel, a spatial arm on
the spatial one, :mod:`dttmm.spatial`).

Overview::

    import dttmm
    case = dttmm.load_case("experiments/cases/three_link.toml")
    res = dttmm.simulate(case, elements_per_link=16, h=1e-3)
    res.tip_deflection[-1], res.meta["iterations_mean"]
"""

from ._version import __version__ as __version__
from .api import accelerations, simulate, statics
from .case import Case, case_from_dict, save_case
from .casefiles import case_to_dict, load_case
from .drives import BangBang, Constant, Drive, Sine, SpinUp, Table
from .errors import InputError, SimulationError
from .linear import Linearization, Modes, frequencies, linearize, modes
from .model import Hub, Link, Manipulator, Payload, RigidBody, Section
from .resources import check_run_size
from .result import Result, make_result, tip_deflection
from .scenario import Scenario
from .urdf_import import load_urdf, read_urdf

__all__ = [
    "Case",
    "load_case",
    "save_case",
    "case_from_dict",
    "case_to_dict",
    "Section",
    "Hub",
    "Payload",
    "RigidBody",
    "Link",
    "Manipulator",
    "Scenario",
    "Drive",
    "Constant",
    "BangBang",
    "Sine",
    "SpinUp",
    "Table",
    "Result",
    "make_result",
    "tip_deflection",
    "InputError",
    "SimulationError",
    "simulate",
    "accelerations",
    "statics",
    "check_run_size",
    "linearize",
    "modes",
    "frequencies",
    "Linearization",
    "Modes",
    "load_urdf",
    "read_urdf",
]
