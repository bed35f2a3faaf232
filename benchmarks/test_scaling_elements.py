"""Cost vs elements per link, every method, on three_link and single_link (fixed step count)."""

import pytest
from conftest import QUICK, H, case, run_benchmark

KS = [1, 4] if QUICK else [1, 2, 4, 8, 16, 32, 64, 128, 256]
KS_DTTMM = KS if QUICK else KS + [512, 1024]
K_MAX = {"global": 64, "dttmm-rk4": 32, "exudyn-ancf": 256, "exudyn-beam": 256}
CASES = ["three_link"] if QUICK else ["three_link", "single_link"]


def _rk4_h(c, k):
    """A stable RK4 step: a fraction of the element's axial wave transit time."""
    b = c.model.links[0].beam
    c_ax = ((b.EA or 1e4 * b.EI / (b.length / k) ** 2) / b.rhoA) ** 0.5
    return min(H, 0.2 * (b.length / k) / c_ax)


@pytest.mark.parametrize("name", CASES)
@pytest.mark.parametrize("k", KS_DTTMM)
@pytest.mark.parametrize("variant", ["converged", "one-shot"])
def test_dttmm_newmark(benchmark, name, k, variant):
    benchmark.group = f"elements:{name}:dttmm-{variant}"
    opts = {"iterations": 0} if variant == "one-shot" else {}
    run_benchmark(benchmark, "dttmm", case(name), k, H, name, cut_loads=False, energy=False, **opts)


@pytest.mark.parametrize("name", CASES)
@pytest.mark.parametrize("k", KS_DTTMM)
def test_dttmm_second_order(benchmark, name, k):
    """The second-order element: the like-for-like partner of the Exudyn elements."""
    benchmark.group = f"elements:{name}:dttmm-2nd"
    run_benchmark(benchmark, "dttmm-2nd", case(name), k, H, name, cut_loads=False, energy=False)


@pytest.mark.parametrize("name", CASES)
@pytest.mark.parametrize("method", ["global", "exudyn-ancf", "exudyn-beam", "dttmm-rk4"])
@pytest.mark.parametrize("k", KS)
def test_reference_methods(benchmark, name, method, k):
    if k > K_MAX[method]:
        pytest.skip(f"{method} is not run beyond k = {K_MAX[method]} (cost)")
    benchmark.group = f"elements:{name}:{method}"
    c = case(name)
    h = _rk4_h(c, k) if method == "dttmm-rk4" else H
    if method == "dttmm-rk4":
        c = case(name, n_steps=10 if QUICK else 50, h=h)
    run_benchmark(benchmark, method, c, k, h, name if method != "dttmm-rk4" else None)


@pytest.mark.parametrize("name", CASES)
def test_pinocchio_rigid(benchmark, name):
    benchmark.group = f"elements:{name}:pinocchio-rigid"
    run_benchmark(benchmark, "pinocchio-rigid", case(name), None, H, name)
