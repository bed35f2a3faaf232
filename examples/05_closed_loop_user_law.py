"""Closed-loop control with your own law: a numba-jitted PD law on the joint angle plus tip
feedback, run by the compiled DT-TMM kernel (quick size: the same law uncompiled)."""

from dataclasses import replace

import numba
import numpy as np
from _gallery import CASES, QUICK, figure_path

import dttmm
from dttmm.drives import Drive, UserLaw

TARGET, KP, KD, KTIP = 0.5, 8.0, 1.0, 40.0  # rad, N·m/rad, N·m·s/rad, N·m/m


@numba.njit
def tip_pd(t, s):  # s: dttmm.drives.JitState of the joint
    tau = KP * (TARGET - s.angle) - KD * s.rate - KTIP * s.tip_deflections[s.joint]
    return tau, -KP, -KD  # τ, ∂τ/∂α, ∂τ/∂α̇ (the kernel treats the law implicitly)


case = dttmm.load_case(CASES / "single_link.toml")
scen = replace(case.scenario, duration=0.3 if QUICK else 3.0, drives=(Drive("torque", UserLaw(tip_pd)),))
case = replace(case, scenario=scen, name="single_link_user_law")
res = dttmm.simulate(case, elements_per_link=4, h=1e-3, engine="python" if QUICK else None, shape_points=9)
print(
    f"joint angle at the end {res.joint_angle[-1, 0]:.4f} rad (target {TARGET}), "
    f"largest tip deflection {1e3 * np.abs(res.tip_deflection).max():.2f} mm"
)

from dttmm.animate import arm_animation, save  # noqa: E402

print("wrote", save(arm_animation(res, case, exaggerate=5, fps=10), figure_path("05_user_law.gif")))
