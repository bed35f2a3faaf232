"""Your own arm as a case file: write a TOML, load it (values are checked on load), run it."""

from dataclasses import replace

from _gallery import QUICK, figure_path

import dttmm

# both links: aluminium strips 40 mm wide (the material form of a link: E, rho, width, thickness)
ALUMINIUM = "E = 70.0e9\nrho = 2700.0\nwidth = 0.04"
TOML = f"""
name = "my_arm"
[model]
gravity = [0.0, -9.81]
[[model.links]]
length = 0.6
thickness = 0.003
{ALUMINIUM}
hub = {{ mass = 0.0, inertia = 0.02 }}
[[model.links]]
length = 0.4
thickness = 0.002
{ALUMINIUM}
hub = {{ mass = 0.3, inertia = 0.001 }}
payload = {{ mass = 0.2, inertia = 0.0 }}
[scenario]
duration = 1.5
output_step = 1e-3
drives = [
    {{ kind = "motion", law = "spin_up", rate = 1.5, ramp_time = 0.8 }},  # joint 1 spins up
    {{ kind = "torque", law = "constant", value = 0.0 }},  # joint 2 swings free
]
"""

path = figure_path("my_arm.toml")
path.write_text(TOML)
case = dttmm.load_case(path)
if QUICK:
    case = replace(case, scenario=replace(case.scenario, duration=0.2))
res = dttmm.simulate(case, elements_per_link=4 if QUICK else 8, h=1e-3, shape_points=9)
print(
    f"{case.name}: joint-1 torque at the end {res.joint_torque[-1, 0]:.3f} N·m, "
    f"tip deflections {res.tip_deflection[-1]} m"
)

try:  # a bad value is refused with the field and the value
    bad = path.with_name("bad.toml")
    bad.write_text(TOML.replace("length = 0.6", "length = -0.6"))
    dttmm.load_case(bad)
except dttmm.InputError as exc:
    print("refused:", exc)

from dttmm.animate import arm_animation, save  # noqa: E402

print("wrote", save(arm_animation(res, case, exaggerate=5, fps=10), figure_path("02_my_arm.gif")))
