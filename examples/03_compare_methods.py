"""Comparing methods on your arm: every registered method on the case of example 02, overlaid
in a plot and in an animation (registry labels and styles)."""

from dataclasses import replace

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
from _gallery import QUICK, figure_path

import dttmm
from dttmm.animate import arm_animation, save
from experiments import methods

path = figure_path("my_arm.toml")
if not path.exists():  # example 02 writes it
    import runpy
    from pathlib import Path

    runpy.run_path(str(Path(__file__).with_name("02_own_arm_case_file.py")))
case = dttmm.load_case(path)
case = replace(case, scenario=replace(case.scenario, duration=0.2 if QUICK else 1.5))
k = 4 if QUICK else 8
runs = {}
for name, h in [
    ("dttmm", 1e-3),
    ("global", 1e-3),
    ("exudyn-ancf", 1e-3),
    ("mujoco-chain", 1e-4),
    ("pinocchio-rigid", 1e-3),
]:
    try:
        runs[name] = methods.run(name, case, k, h, shape_points=9)
    except methods.MethodUnavailable as exc:
        print(f"{name}: unavailable ({exc})")
        continue
    r = runs[name]
    print(
        f"{methods.label(name):40s} tip 2 at the end {1e3 * r.tip_deflection[-1, 1]:8.3f} mm, solve {r.wall_time:.3f} s"
    )

fig, ax = plt.subplots(figsize=(6, 3.2))
for name, r in runs.items():
    st = methods.style(name)
    ax.plot(r.t, 1e3 * r.tip_deflection[:, 1], color=st.color, ls=st.linestyle, label=methods.label(name))
ax.set(xlabel="t [s]", ylabel="link-2 tip deflection [mm]")
ax.legend(fontsize=7)
fig.tight_layout()
fig.savefig(figure_path("03_compare_methods.png"), dpi=100)
looks = {n: (methods.label(n), methods.style(n).color, methods.style(n).linestyle) for n in runs}
anim = arm_animation(runs, case, exaggerate=5, fps=10, styles=looks)
print("wrote", save(anim, figure_path("03_compare_methods.gif")))
