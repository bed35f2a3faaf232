"""Your robot from its URDF, in three steps: load the UR5 of example-robot-data, declare its
upper arm and forearm flexible (aluminium tubes from the section calculator), run a
pick-and-place move and compare the tool point with the rigid robot (docs/urdf.md)."""

from importlib import metadata

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
from _gallery import CASES, QUICK, figure_path

import dttmm
from dttmm import Drive, Scenario, Table

try:  # the URDFs of example-robot-data (pip install 'dttmm[robots]')
    metadata.distribution("example-robot-data")
    source, tool = "example-robot-data:ur_description/urdf/ur5_robot.urdf", "tool0"
    flexible_links = ("upper_arm_link", "forearm_link")
except metadata.PackageNotFoundError:  # without it: a URDF written by `dttmm urdf`
    from dttmm.urdf import case_to_urdf

    source, tool = figure_path("rigid_arm.urdf"), "tip"
    source.write_text(case_to_urdf(dttmm.load_case(CASES / "spatial" / "rigid" / "rigid_arm.toml")))
    flexible_links = ("link2",)
    print("example-robot-data is not installed: the arm of experiments/cases/spatial/rigid/rigid_arm.toml")

# 1. load: every link rigid, as the URDF says (fixed joints merged, limits kept)
rigid = dttmm.read_urdf(source, tool=tool)
print(f"{rigid.name}: joints {', '.join(rigid.joints)}")
print("limits (rad):", {lim.joint: (lim.lower, lim.upper) for lim in rigid.limits})

# 2. declare the flexible links: a tube of 6061-T6 aluminium, the URDF body kept at its root
tube = {"section": {"tube": {"outer_diameter": 0.085, "wall": 0.004}}, "material": "aluminium"}
flexible = dttmm.read_urdf(source, {n: {**tube, "keep_inertia": True} for n in flexible_links}, tool=tool)

# 3. run a pick-and-place move (every joint a rest-to-rest spline) and compare with the rigid arm
duration = 0.3 if QUICK else 1.0
times = (0.0, 0.3 * duration, 0.7 * duration, duration)
goal = np.array([0.8, -0.4, 0.6, -0.2, 0.0, 0.3])[: len(rigid.joints)]
drives = tuple(Drive("motion", Table(times, (0.0, 0.15 * g, 0.85 * g, g))) for g in goal)
scenario = Scenario(duration, 1e-3, drives)
k = 2 if QUICK else 4
res = dttmm.simulate(flexible.case(scenario), elements_per_link=k, h=1e-3)
ref = dttmm.simulate(rigid.case(scenario), elements_per_link=1, h=1e-3)
gap = np.linalg.norm(res.end_effector - ref.end_effector, axis=1)
print(f"{res.status}: tool point {1e3 * gap.max():.3f} mm at most from the rigid robot's over {duration} s")

fig, ax = plt.subplots(figsize=(6, 3))
ax.plot(res.t, 1e3 * gap)
ax.set(xlabel="t [s]", ylabel="tool point gap [mm]", title=f"{rigid.name}: flexible vs rigid links")
fig.tight_layout()
fig.savefig(figure_path("09_robot_from_urdf.png"), dpi=100)
