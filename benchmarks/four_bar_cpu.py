"""The flexible four-bar over the paper's 12 s: accuracy and CPU time of the DT-TMM and of
Exudyn's 3-D geometrically exact beam, in one run (docs/spatial.md §6).

``python benchmarks/four_bar_cpu.py [--duration 12] [--repeats 3]`` runs
``experiments/cases/spatial/topology/four_bar.toml`` for ``--duration`` seconds with both engines
at generalized-α ρ∞ = 0.8, h = 1 ms, output every 0.01 s: the DT-TMM at k = 2, 4, 8, 16 and
Exudyn at k = 7, 15 (odd, so that an element's centre, where its section loads are, is BC's
mid-span). Accuracy: the largest difference of BC's mid-span deflection (its centre line's
midpoint minus its chord's, world z) and mid-span moment |M| histories from Exudyn's at k = 15,
in % of their peaks. Cost: process time of the whole call (model build included), the least of
``--repeats`` calls after one warm-up call, one BLAS thread (``threadpoolctl``).
"""

from __future__ import annotations

import argparse
import dataclasses
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
CASE = ROOT / "experiments" / "cases" / "spatial" / "topology" / "four_bar.toml"


def cpu_time(fn, repeats: int):
    """Least process time (s) of ``repeats`` calls of ``fn`` after one warm-up call, and the
    last call's result."""
    res = fn()
    best = float("inf")
    for _ in range(repeats):
        t0 = time.process_time()
        res = fn()
        best = min(best, time.process_time() - t0)
    return best, res


def mid_span(res, k: int | None):
    """BC's mid-span deflection (world z) and |M| at its mid-span: the DT-TMM's cut k // 2 of
    link 2 (k even), Exudyn's recorded middle element (``k`` None)."""
    s = res.link_shapes[:, 1]
    deflection = (s[:, 1] - 0.5 * (s[:, 0] + s[:, 2]))[:, 2]
    loads = res.cut_loads[:, 1] if k is None else res.cut_loads[:, (k + 1) + k // 2]
    return deflection, np.linalg.norm(loads[:, 3:], axis=1)


def main(argv=None) -> None:
    from threadpoolctl import threadpool_limits

    import dttmm
    import dttmm.spatial as sp
    from reference_models import exudyn_beam3d

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--duration", type=float, default=12.0)
    ap.add_argument("--repeats", type=int, default=3)
    args = ap.parse_args(argv)
    case = dttmm.load_case(CASE)
    case = dataclasses.replace(
        case, scenario=dataclasses.replace(case.scenario, duration=args.duration, output_step=0.01)
    )
    runs = {}
    with threadpool_limits(1):
        for k in (7, 15):
            fn = lambda k=k: exudyn_beam3d.simulate(
                case, elements_per_link=k, h=1e-3, rho_inf=0.8, shape_points=3, section_loads="middle"
            )
            cpu, res = cpu_time(fn, args.repeats)
            runs[f"exudyn-beam k = {k}"] = (cpu, *mid_span(res, None))
        for k in (2, 4, 8, 16):
            fn = lambda k=k: sp.simulate(
                case, elements_per_link=k, h=1e-3, integrator="generalized-alpha", rho_inf=0.8,
                shape_points=3, cut_loads=True, progress=False,
            )  # fmt: skip
            cpu, res = cpu_time(fn, args.repeats)
            runs[f"dttmm k = {k}"] = (cpu, *mid_span(res, k))
    _, d_ref, m_ref = runs["exudyn-beam k = 15"]
    print(f"four-bar, {args.duration:g} s; reference: exudyn-beam k = 15 (peaks {np.max(np.abs(d_ref)):.4e} m, "
          f"{np.max(m_ref):.4g} N·m)")  # fmt: skip
    print(f"{'run':<22}{'deflection %':>14}{'moment %':>10}{'CPU s':>9}")
    for name, (cpu, d, m) in runs.items():
        dd = 100 * np.max(np.abs(d - d_ref)) / np.max(np.abs(d_ref))
        dm = 100 * np.max(np.abs(m - m_ref)) / np.max(m_ref)
        print(f"{name:<22}{dd:>14.2f}{dm:>10.2f}{cpu:>9.2f}")


if __name__ == "__main__":
    main()
