"""DT-TMM against the compiled global-equation solver, same discretisation and iteration.

Cost in k (three_link, k elements per link) and in n (chains of n links at k = 8), and the
compiled global engine against the same source uncompiled (``engine="python"``). The number of steps shrinks with the size
so the O(N³) global runs stay short; ``extra_info["time_per_step"]`` is the comparable
figure. ``experiments/global_scaling.py`` turns the same runs into a table with fitted
exponents and crossovers.
"""

import pytest
from conftest import QUICK, H, case, chain, run_benchmark

KS = [1, 4] if QUICK else [1, 2, 4, 8, 16, 32, 64, 128, 256]
NS = [1, 3] if QUICK else [1, 2, 3, 4, 6, 8, 12]
K_LINKS = 8
K_ENGINES = [4] if QUICK else [4, 16]  # uncompiled: ~10 s per step at k = 64


def _steps(n_dof_scale: int) -> int:
    """Steps for a run whose global solve has about n_dof_scale coordinates."""
    if QUICK:
        return 5
    return 100 if n_dof_scale <= 300 else 20 if n_dof_scale <= 600 else 5


@pytest.mark.parametrize("k", KS)
@pytest.mark.parametrize("method", ["dttmm", "global"])
def test_global_vs_dttmm_elements(benchmark, method, k):
    benchmark.group = f"global-k:{method}"
    run_benchmark(benchmark, method, case("three_link", _steps(9 * k)), k, H, None)


@pytest.mark.parametrize("n", NS)
@pytest.mark.parametrize("method", ["dttmm", "global"])
def test_global_vs_dttmm_links(benchmark, method, n):
    benchmark.group = f"global-n:{method}"
    run_benchmark(benchmark, method, chain(n, _steps(3 * K_LINKS * n)), K_LINKS, H, None)


@pytest.mark.parametrize("k", K_ENGINES)
@pytest.mark.parametrize("engine", ["numba", "python"])
def test_global_engines(benchmark, engine, k):
    benchmark.group = f"global-engine:{engine}"
    res = run_benchmark(
        benchmark,
        "global",
        case("three_link", max(1, _steps(9 * k) // (20 if engine == "python" else 1))),
        k,
        H,
        None,
        engine=engine,
    )
    assert res.meta["engine"] == engine
