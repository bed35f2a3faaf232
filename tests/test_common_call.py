"""The common call's checks (``dttmm.plumbing.discretisation``), the same in every method:
``elements_per_link`` an integer ≥ 1 (no bool, no float such as 4.0, no string) and ``h`` a
positive finite real number (no bool, no string) at most the duration, each refused with a
one-line InputError naming the field and the value. A bad value is refused before any
engine work, so these tests compile nothing."""

from __future__ import annotations

import importlib
import math

import numpy as np
import pytest

from dttmm import Constant, Drive, InputError, Link, Manipulator, Scenario, Section
from dttmm.case import Case

# every method's simulate: (module, uses elements_per_link)
METHODS = [
    ("dttmm", True),
    ("reference_models.global_newmark", True),
    ("reference_models.exudyn_ancf", True),
    ("reference_models.exudyn_beam", True),
    ("reference_models.mujoco_chain", True),
    ("reference_models.pinocchio_rigid", False),
]
ENGINES = {
    "exudyn_ancf": "exudyn",
    "exudyn_beam": "exudyn",
    "mujoco_chain": "mujoco",
    "pinocchio_rigid": "pinocchio",
}

BAD_K = [4.0, True, "4", 0, -1, None, 2.5]
BAD_H = [True, "0.001", 0.0, -1e-3, math.nan, math.inf, None, 0.5]  # 0.5 > the duration 0.01


def _simulate(module: str):
    engine = ENGINES.get(module.rsplit(".", 1)[-1])
    if engine:
        pytest.importorskip(engine)
    return importlib.import_module(module).simulate


def _case() -> Case:
    link = Link(Section(1.0, 2.0, 0.3, 7e6), hub=None, payload=None)
    return Case(Manipulator((link,)), Scenario(0.01, 0.002, (Drive("torque", Constant(0.1)),)), "probe")


@pytest.mark.parametrize("module,uses_k", METHODS, ids=[m for m, _ in METHODS])
@pytest.mark.parametrize("k", BAD_K, ids=repr)
def test_bad_elements_per_link_is_refused_naming_field_and_value(module, uses_k, k):
    simulate = _simulate(module)
    if not uses_k and k is None:
        pytest.skip("the rigid baseline takes elements_per_link=None")
    with pytest.raises(InputError) as exc:
        simulate(_case(), elements_per_link=k, h=1e-3)
    assert exc.value.field == "elements_per_link"
    assert repr(k) in str(exc.value) and "\n" not in str(exc.value)


@pytest.mark.parametrize("module,uses_k", METHODS, ids=[m for m, _ in METHODS])
@pytest.mark.parametrize("h", BAD_H, ids=repr)
def test_bad_step_is_refused_naming_field_and_value(module, uses_k, h):
    simulate = _simulate(module)
    with pytest.raises(InputError) as exc:
        simulate(_case(), elements_per_link=2 if uses_k else None, h=h)
    assert exc.value.field == "h"
    assert repr(h) in str(exc.value) and "\n" not in str(exc.value)


@pytest.mark.parametrize("module,uses_k", METHODS, ids=[m for m, _ in METHODS])
def test_a_numpy_integer_k_passes_the_check(module, uses_k):
    """np.int64 is an integer k in every method (sweeps build k with numpy): with it, the
    check goes on to h and refuses the bad step."""
    simulate = _simulate(module)
    with pytest.raises(InputError) as exc:
        simulate(_case(), elements_per_link=np.int64(3), h=-1.0)
    assert exc.value.field == "h"
