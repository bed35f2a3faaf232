"""CPU time of each method on the shipped robots' pick-and-place trajectory (docs/urdf.md).

``python benchmarks/robots_cpu.py [--k 8] [--h 1e-3] [--repeats 3]`` runs the UR5 and the Panda
of ``experiments/cases/spatial/robots/`` (1 s, their upper arm and forearm aluminium tubes) by
the spatial DT-TMM, Exudyn's 3-D geometrically exact beam (``reference_models.exudyn_beam3d``)
and Pinocchio's rigid arm (``reference_models.pinocchio_spatial``, RK4), each timed as the
process time of the whole call (model build included), the least of ``--repeats`` calls after
one warm-up call, with one BLAS thread (``threadpoolctl``), and prints the CPU time and the
real-time factor (CPU time / simulated time: below 1 is faster than real time).
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
ROBOTS = ROOT / "experiments" / "cases" / "spatial" / "robots"


def _methods():
    import dttmm.spatial as sp
    from reference_models import exudyn_beam3d, pinocchio_spatial

    return {
        "dttmm (Newmark)": lambda case, k, h: sp.simulate(case, elements_per_link=k, h=h),
        "exudyn-beam (GE beam 3D)": lambda case, k, h: exudyn_beam3d.simulate(case, elements_per_link=k, h=h),
        "pinocchio (rigid, RK4)": lambda case, k, h: pinocchio_spatial.simulate(case, h=h),
    }


def cpu_time(fn, repeats: int) -> float:
    """Least process time (s) of ``repeats`` calls of ``fn`` after one warm-up call."""
    fn()
    best = float("inf")
    for _ in range(repeats):
        t0 = time.process_time()
        fn()
        best = min(best, time.process_time() - t0)
    return best


def main(argv=None) -> int:
    from threadpoolctl import threadpool_limits

    import dttmm

    ap = argparse.ArgumentParser(prog="python benchmarks/robots_cpu.py")
    ap.add_argument("--k", type=int, default=8, help="elements per flexible link (8)")
    ap.add_argument("--h", type=float, default=1e-3, help="step (s) of every method (1e-3)")
    ap.add_argument("--repeats", type=int, default=3)
    a = ap.parse_args(argv)
    print(f"k = {a.k}, h = {a.h:g} s, least process time of {a.repeats} calls, one BLAS thread")
    print(f"{'robot':6} {'method':26} {'CPU (s)':>8} {'T (s)':>6} {'CPU/T':>7}")
    with threadpool_limits(limits=1):
        for name in ("ur5", "panda"):
            case = dttmm.load_case(ROBOTS / f"{name}.toml")
            T = case.scenario.duration
            for label, run in _methods().items():
                t = cpu_time(lambda run=run, case=case: run(case, a.k, a.h), a.repeats)
                print(f"{name:6} {label:26} {t:8.3f} {T:6.2f} {t / T:7.3f}", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
