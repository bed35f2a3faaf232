"""Closed-loop control with your own law: a rest-to-rest move of the single-link arm to 0.5 rad
under a numba-jitted PD law, without and with feedback of the tip deflection; the law runs in
the compiled DT-TMM kernel (quick size: the same law in the uncompiled kernel)."""

from dataclasses import replace

import numba
import numpy as np
from _gallery import CASES, QUICK, figure_path

import dttmm
from dttmm.animate import arm_animation, save
from dttmm.drives import Drive, UserLaw


def pd_law(kp, kd, k_tip):
    """τ = kp (0.5 − α) − kd α̇ + k_tip w_tip, with its slopes ∂τ/∂α, ∂τ/∂α̇ (the kernel treats
    the law implicitly); s is the joint's dttmm.drives.JitState."""

    @numba.njit
    def law(t, s):
        return kp * (0.5 - s.angle) - kd * s.rate + k_tip * s.tip_deflections[s.joint], -kp, -kd

    return law


base = dttmm.load_case(CASES / "single_link.toml")
T = 0.5 if QUICK else 4.0
for name, k_tip in (("PD", 0.0), ("PD + tip feedback", -5.0)):
    scen = replace(base.scenario, duration=T, drives=(Drive("torque", UserLaw(pd_law(2.0, 0.5, k_tip))),))
    case = replace(base, scenario=scen, name="single_link_user_law")
    res = dttmm.simulate(
        case, elements_per_link=4, h=1e-3, engine="python" if QUICK else None, shape_points=9
    )
    late = res.t >= 0.75 * T
    print(
        f"{name:18s} angle at the end {res.joint_angle[-1, 0]:.4f} rad, peak tip deflection "
        f"{1e3 * np.abs(res.tip_deflection).max():.1f} mm, in the last quarter "
        f"{1e3 * np.abs(res.tip_deflection[late]).max():.3f} mm"
    )
print("wrote", save(arm_animation(res, case, fps=10), figure_path("05_user_law.gif")))
