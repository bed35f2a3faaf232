"""URDF export of a spatial case's rigid limit (dttmm.urdf): frames and mass matrix of the
URDF model, built by Pinocchio, against the spatial kernel's own kinematics and kinetic energy
at zero elastic coordinates (where the flexible arm's joint-space mass matrix is that of its
rigid limit, exactly)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from dttmm.cli import main as cli_main
from dttmm.spatial import load_case
from dttmm.spatial.build import build_model, make_work
from dttmm.spatial.kernel import core
from dttmm.urdf import case_to_urdf

pin = pytest.importorskip("pinocchio")
CASES = Path(__file__).resolve().parent.parent / "experiments" / "cases" / "spatial"


def _kernel_mass_and_tips(case, alpha):
    md = build_model(case.model, 1)
    ws = make_work(md)
    n = md.ndof
    q = np.zeros(n)
    q[md.ia[md.ia >= 0]] = alpha
    ia = md.ia[md.ia >= 0]

    def T(v):
        qd = np.zeros(n)
        qd[ia] = v
        core.kinematics(md, ws, q, qd)
        e = core.energy(md, ws)
        core.kinematics(md, ws, q, np.zeros(n))
        return e - core.energy(md, ws)

    m = ia.size
    I = np.eye(m)
    M = np.array(
        [[T(I[a] + I[b]) - T(I[a]) - T(I[b]) if a != b else 2 * T(I[a]) for b in range(m)] for a in range(m)]
    )
    core.kinematics(md, ws, q, np.zeros(n))
    return M, ws.pT[1:].copy()


@pytest.mark.parametrize("name", ["two_joint_arm", "three_joint_arm", "cantilever_3d"])
def test_urdf_rigid_limit_matches_the_kernel(name):
    case = load_case(CASES / f"{name}.toml")
    model = pin.buildModelFromXML(case_to_urdf(case))
    data = model.createData()
    assert model.nq == case.model.n_joints
    rng = np.random.default_rng(4)
    for _ in range(3):
        alpha = rng.uniform(-3, 3, size=model.nq)
        M, tips = _kernel_mass_and_tips(case, alpha)
        if model.nq:
            Mp = pin.crba(model, data, alpha)
            Mp = np.triu(Mp) + np.triu(Mp, 1).T
            np.testing.assert_allclose(Mp, M, rtol=1e-9, atol=1e-12 * np.abs(M).max())
        pin.framesForwardKinematics(model, data, alpha)
        for i in range(case.model.n_links):
            p = data.oMf[model.getFrameId(f"link{i + 1}_tip")].translation
            np.testing.assert_allclose(p, tips[i], rtol=0, atol=1e-12)


def test_cli_writes_a_spatial_urdf(capsys):
    assert cli_main(["urdf", str(CASES / "three_joint_arm.toml")]) == 0
    out = capsys.readouterr().out
    assert 'name="joint3"' in out and "gravity" in out and "-9.81" in out
