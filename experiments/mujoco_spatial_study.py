"""Measurements of the MuJoCo spatial chain (docs/mujoco.md, "Spatial chain"): convergence in k
against the spatial DT-TMM, the three station variants, and the cost per step.

    PYTHONPATH=. OPENBLAS_NUM_THREADS=1 python experiments/mujoco_spatial_study.py [--k32]

Reference: ``dttmm.spatial.simulate`` at k = 32, h = 1.25e-4 (Newmark). The chain runs on its
stable path: h = the largest 1e-3/2^m at or below 0.8·h_stable. CPU times: ``time.process_time``
of the stepping only (``meta["cpu_time_solve"]``), least of 3 repeats.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

import dttmm.spatial as ds
from reference_models import mujoco_spatial as ms

CASES = Path(__file__).resolve().parent / "cases" / "spatial"


def stable_h(c, k, H=1e-3):
    m, d, _ = ms.build(c.model, k)
    hs = ms.stability_limit(m, d)[1]
    return H / 2 ** max(0, int(np.ceil(np.log2(H / (0.8 * hs))))), hs


def errors(r, a):
    tw = np.abs(a.twist).max(axis=0)
    return {
        "q (rad)": np.abs(r.joint_angle - a.joint_angle).max(),
        "ee (m)": np.abs(r.end_effector - a.end_effector).max(),
        "defl (rel)": np.abs(r.tip_deflection - a.tip_deflection).max() / np.abs(a.tip_deflection).max(),
        "twist 1 (rel)": np.abs(r.twist[:, 0] - a.twist[:, 0]).max() / tw[0],
        "twist 2 (rel)": np.abs(r.twist[:, 1] - a.twist[:, 1]).max() / tw[1],
    }


def cpu(c, k, h, repeats=3, **opts):
    best, r = np.inf, None
    for _ in range(repeats):
        r = ms.simulate(c, elements_per_link=k, h=h, **opts)
        best = min(best, r.meta["cpu_time_solve"])
    return r, best


def main(ks=(2, 4, 8, 16)):
    for name in ("two_joint_arm", "three_joint_arm"):
        c = ds.load_case(CASES / f"{name}.toml")
        a = ds.simulate(c, elements_per_link=32, h=1.25e-4)
        print(f"\n## {name}: convergence along the stable path (reference DT-TMM k = 32, h = 1.25e-4)")
        print("| k | n_dof | ω_max (rad/s) | h (s) | " + " | ".join(errors(a, a)) + " | µs per step |")
        for k in ks:
            h, hs = stable_h(c, k)
            r, t = cpu(c, k, h, repeats=3 if k <= 8 else 1)
            e = errors(r, a)
            row = " | ".join(f"{v:.2e}" for v in e.values())
            print(
                f"| {k} | {r.meta['n_dof']} | {r.meta['omega_max']:.4g} | {h:.4g} | {row} | {1e6 * t / r.n_steps:.1f} |"
            )
        print(f"\n## {name}: station variants at the same h (1e-3/2^m ≤ 0.4·h_stable)")
        print("| station | k | " + " | ".join(errors(a, a)) + " | µs per step |")
        for k in (4, 8, 16):
            h = stable_h(c, k)[0] / 2
            for st in ms.STATIONS:
                r, t = cpu(c, k, h, repeats=3 if k <= 8 else 1, station=st)
                row = " | ".join(f"{v:.2e}" for v in errors(r, a).values())
                print(f"| {st} | {k} | {row} | {1e6 * t / r.n_steps:.1f} |")


if __name__ == "__main__":
    main((2, 4, 8, 16, 32) if "--k32" in sys.argv else (2, 4, 8, 16))
