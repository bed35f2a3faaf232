"""Cost of the MuJoCo hinge chain per element-step on three_link, against DT-TMM at the same step.

The chain integrates its joint springs explicitly, so the step is set by stability: the
largest H/2^m below 0.8·h_stable (h_stable = 2/ω_max of the chain, ∝ 1/k²). DT-TMM runs the
same step count at the same h, so ``time_per_element_step`` of both compares like for like.
"""

import math

import pytest
from conftest import QUICK, H, case, run_benchmark

KS = [4] if QUICK else [4, 16, 64]
N_STEPS = 10 if QUICK else 5000


def _stable_h(k: int) -> float:
    mc = pytest.importorskip("reference_models.mujoco_chain")
    m, d, _ = mc.build(case("three_link").model, k, H)
    _, h_stable = mc.stability_limit(m, d, "implicitfast")
    return H / 2 ** max(0, math.ceil(math.log2(H / (0.8 * h_stable))))


@pytest.mark.parametrize("method", ["mujoco-chain", "dttmm"])
@pytest.mark.parametrize("k", KS)
def test_element_step(benchmark, method, k):
    h = _stable_h(k)
    benchmark.group = f"mujoco-vs-dttmm:three_link:k={k}"
    opts = {"cut_loads": False, "energy": False} if method == "dttmm" else {}
    res = run_benchmark(benchmark, method, case("three_link", n_steps=N_STEPS, h=h), k, h, None, **opts)
    assert res.n_steps == N_STEPS
