"""Cost of one step at equal model size: DT-TMM vs global vs Exudyn (three_link)."""

import pytest
from conftest import QUICK, H, case, run_benchmark

KS = [4] if QUICK else [4, 16, 64]


@pytest.mark.parametrize("k", KS)
@pytest.mark.parametrize("method", ["dttmm", "global", "exudyn-ancf", "exudyn-beam"])
def test_one_step(benchmark, method, k):
    """10 steps, reported per step in extra_info (time_per_step, solve only)."""
    benchmark.group = f"one-step:k={k}"
    run_benchmark(benchmark, method, case("three_link", n_steps=10), k, H, None)
