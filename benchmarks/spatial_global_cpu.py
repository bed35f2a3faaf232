"""The spatial global-equation solver's two engines against the spatial DT-TMM, in one run: CPU
time per step as the elements per link grow (docs/spatial.md "Global solver: compiled
mechanics").

``python benchmarks/spatial_global_cpu.py [--duration 0.2] [--repeats 3] [--ks 2 4 8 16 32]``
runs ``experiments/cases/spatial/three_joint_arm.toml`` for ``--duration`` seconds, Newmark,
h = 1 ms, outputs and cut loads at every step: the spatial global solver with its compiled
mechanics (``engine="numba"``, composite inertias, O(N²) per state) and its readable numpy
mechanics (``engine="numpy"``, dense Jacobians, O(N³); up to k = 16), and the spatial DT-TMM
(same discretisation and iteration). Process time of the whole call, the least of ``--repeats``
calls after one warm-up call, one BLAS thread (``threadpoolctl``); the largest end-effector
difference of each run from the DT-TMM's.
"""

from __future__ import annotations

import argparse
import dataclasses
from pathlib import Path

import numpy as np
from four_bar_cpu import cpu_time

ROOT = Path(__file__).resolve().parents[1]
CASE = ROOT / "experiments" / "cases" / "spatial" / "three_joint_arm.toml"
NUMPY_MAX_K = 16  # the numpy engine: 0.12 s a step at k = 16


def main(argv=None) -> None:
    from threadpoolctl import threadpool_limits

    import dttmm
    import dttmm.spatial as sp
    from reference_models import spatial_global

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--duration", type=float, default=0.2)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--ks", type=int, nargs="+", default=[2, 4, 8, 16, 32])
    args = ap.parse_args(argv)
    case = dttmm.load_case(CASE)
    case = dataclasses.replace(
        case, scenario=dataclasses.replace(case.scenario, duration=args.duration, output_step=1e-3)
    )
    kw = {"h": 1e-3, "cut_loads": True}
    print(
        f"three_joint_arm, {args.duration:g} s, Newmark h = 1 ms, outputs and cut loads every step; ms per step"
    )
    print(
        f"{'k':>3}{'N':>6}{'dttmm':>9}{'numba':>9}{'numpy':>9}{'numpy/numba':>13}{'numba/dttmm':>13}{'|Δee| m':>10}"
    )
    with threadpool_limits(1):
        for k in args.ks:
            t_d, ref = cpu_time(
                lambda k=k: sp.simulate(case, elements_per_link=k, progress=False, **kw), args.repeats
            )
            t_c, res = cpu_time(
                lambda k=k: spatial_global.simulate(case, elements_per_link=k, engine="numba", **kw),
                args.repeats,
            )
            t_n = np.nan
            if k <= NUMPY_MAX_K:
                t_n, _ = cpu_time(
                    lambda k=k: spatial_global.simulate(case, elements_per_link=k, engine="numpy", **kw),
                    args.repeats,
                )
            steps = res.n_steps
            gap = float(np.abs(res.end_effector - ref.end_effector).max())
            print(
                f"{k:>3}{res.meta['n_dof']:>6}{1e3 * t_d / steps:>9.2f}{1e3 * t_c / steps:>9.2f}"
                f"{1e3 * t_n / steps:>9.2f}{t_n / t_c:>13.1f}{t_c / t_d:>13.1f}{gap:>10.1e}"
            )


if __name__ == "__main__":
    main()
