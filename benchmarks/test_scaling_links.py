"""Cost vs number of links: chains of n equal links at k = 8 per link."""

import pytest
from conftest import QUICK, H, chain, run_benchmark

NS = [1, 3] if QUICK else [1, 2, 3, 5, 8, 12]
K = 8


@pytest.mark.parametrize("n", NS)
@pytest.mark.parametrize("method", ["dttmm", "global", "exudyn-ancf"])
def test_links(benchmark, method, n):
    benchmark.group = f"links:{method}"
    run_benchmark(benchmark, method, chain(n), K, H, f"chain{n}")
    benchmark.extra_info["n_links"] = n
