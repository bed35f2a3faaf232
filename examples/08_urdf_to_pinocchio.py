"""Exporting URDF to Pinocchio: the rigid arm of a case as URDF (``dttmm urdf CASE``), loaded by
Pinocchio; its forward dynamics checked against the suite's rigid baseline, whose run is then
compared with the flexible arm."""

from dataclasses import replace

import numpy as np
import pinocchio as pin
from _gallery import CASES, QUICK, figure_path

import dttmm
from dttmm.urdf import case_to_urdf
from experiments import methods
from reference_models.pinocchio_rigid import build_model

case = dttmm.load_case(CASES / "three_link.toml")
path = figure_path("three_link.urdf")
path.write_text(case_to_urdf(case))
model = pin.buildModelFromUrdf(str(path))
model.gravity.linear = np.array([*case.model.gravity, 0.0])  # URDF carries no gravity
direct = build_model(case.model)
q, v, tau = np.array([0.3, -0.5, 0.8]), np.array([0.1, 0.2, -0.3]), np.array([1.0, 0.2, 0.0])
a_urdf = pin.aba(model, model.createData(), q, v, tau)
a_direct = pin.aba(direct, direct.createData(), q, v, tau)
print(
    f"{model.name}: joint accelerations from the URDF {np.round(a_urdf, 6)} rad/s², "
    f"largest difference to the suite's model {np.abs(a_urdf - a_direct).max():.1e}"
)
assert np.allclose(a_urdf, a_direct, rtol=1e-10, atol=1e-10)

short = replace(case, scenario=replace(case.scenario, duration=0.2 if QUICK else 2.0))
rigid = methods.run("pinocchio-rigid", short, None, 1e-3)
flex = dttmm.simulate(short, elements_per_link=4 if QUICK else 8, h=1e-3)
gap = np.linalg.norm(rigid.end_effector - flex.end_effector, axis=1)
print(
    f"end-effector gap, rigid vs flexible: {1e3 * gap.max():.2f} mm at most over {short.scenario.duration} s"
)
