"""URDF export of the rigid arm (dttmm.urdf) and the ``dttmm urdf`` command."""

import os
import shutil
import subprocess
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest

import dttmm
from dttmm.cli import main as cli_main
from dttmm.urdf import case_to_urdf

CASES = Path(__file__).resolve().parents[1] / "experiments" / "cases"
THREE = CASES / "three_link.toml"


def test_urdf_structure():
    case = dttmm.load_case(THREE)
    root = ET.fromstring(case_to_urdf(case))
    assert root.tag == "robot" and root.get("name") == "three_link"
    joints = {j.get("name"): j for j in root.iter("joint")}
    for i, link in enumerate(case.model.links, start=1):
        j = joints[f"joint{i}"]
        assert j.get("type") == "revolute" and j.find("axis").get("xyz") == "0 0 1"
        inertial = root.find(f"link[@name='link{i}']/inertial")
        m, L = link.beam.mass, link.beam.length
        assert float(inertial.find("mass").get("value")) == m
        assert float(inertial.find("origin").get("xyz").split()[0]) == L / 2
        assert float(inertial.find("inertia").get("izz")) == m * L * L / 12
        hub = root.find(f"link[@name='hub{i}']/inertial")
        assert float(hub.find("inertia").get("izz")) == link.hub.inertia
    assert float(root.find("link[@name='payload3']/inertial/mass").get("value")) == 0.1
    assert root.find("link[@name='tip']") is not None
    assert root.find("link[@name='payload1']") is None  # only where the case has one


def test_urdf_matches_programmatic_model():
    pin = pytest.importorskip("pinocchio")
    from reference_models.pinocchio_rigid import build_model

    case = dttmm.load_case(THREE)
    from_urdf = pin.buildModelFromXML(case_to_urdf(case))
    direct = build_model(case.model)
    assert from_urdf.nq == from_urdf.nv == 3
    assert [from_urdf.joints[i].shortname() for i in (1, 2, 3)] == ["JointModelRZ"] * 3
    from_urdf.gravity.linear = np.array([*case.model.gravity, 0.0])  # URDF carries no gravity
    du, dd = from_urdf.createData(), direct.createData()
    rng = np.random.default_rng(0)
    for _ in range(5):
        q, v, tau = rng.normal(0, 2, (3, 3))
        np.testing.assert_allclose(pin.crba(from_urdf, du, q), pin.crba(direct, dd, q), rtol=0, atol=1e-12)
        np.testing.assert_allclose(
            pin.aba(from_urdf, du, q, v, tau), pin.aba(direct, dd, q, v, tau), rtol=0, atol=1e-12
        )
        pin.framesForwardKinematics(from_urdf, du, q)
        pin.framesForwardKinematics(direct, dd, q)
        for name in ("tip", "link1_tip", "link2_tip"):
            np.testing.assert_allclose(
                du.oMf[from_urdf.getFrameId(name)].translation,
                dd.oMf[direct.getFrameId(name)].translation,
                rtol=0,
                atol=1e-14,
            )


def test_cli_prints_urdf(capsys):
    assert cli_main(["urdf", str(THREE)]) == 0
    out = capsys.readouterr().out
    root = ET.fromstring(out)
    assert len([j for j in root.iter("joint") if j.get("type") == "revolute"]) == 3
    assert "-9.81" in out  # gravity noted in the comment


def test_cli_out_file(tmp_path, capsys):
    target = tmp_path / "arm.urdf"
    assert cli_main(["urdf", str(CASES / "single_link.toml"), "--out", str(target)]) == 0
    assert capsys.readouterr().out == ""
    assert ET.parse(target).getroot().get("name") == "single_link"


def test_cli_missing_case(capsys):
    assert cli_main(["urdf", "no/such/case.toml"]) == 2
    assert "no/such/case.toml" in capsys.readouterr().err


def test_console_script():
    exe = Path(sys.executable).with_name("dttmm")
    exe = str(exe) if exe.exists() else shutil.which("dttmm")
    if exe is None:
        pytest.skip("the dttmm console script is not installed")
    root = str(Path(__file__).resolve().parents[1])  # this checkout's code, whatever the package points to
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([root, os.environ.get("PYTHONPATH", "")])}
    out = subprocess.run(
        [exe, "urdf", str(THREE)], capture_output=True, text=True, check=True, env=env
    ).stdout
    assert ET.fromstring(out).get("name") == "three_link"


def test_cli_unwritable_out_is_one_line_exit_2(tmp_path, capsys):
    blocker = tmp_path / "file"
    blocker.write_text("")
    assert cli_main(["urdf", str(CASES / "single_link.toml"), "--out", str(blocker / "arm.urdf")]) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and "--out" in err
