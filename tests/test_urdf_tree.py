"""Branched robots from a URDF (dttmm/urdf_import.py; docs/urdf.md "Branched robots"): the
import of a kinematic tree (each moving body's parent follows the URDF tree), its refusals,
the rigid tree against Pinocchio's own reading of the same URDF (ABA at random states) on a
small tree written for this test and on example-robot-data's Allegro hand and Baxter, and a
flexible link on one branch against the spatial global solver (the same discrete equations)
and against Exudyn's 3-D beam (the static sag)."""

from __future__ import annotations

import numpy as np
import pytest

import dttmm
import dttmm.spatial as sp
from dttmm import Constant, Drive, Scenario, Sine
from dttmm.urdf_import import case_from_urdf_dict, read_urdf

ALLEGRO = "example-robot-data:allegro_hand_description/urdf/allegro_right_hand.urdf"
BAXTER = "example-robot-data:baxter_description/urdf/baxter.urdf"


def _inertial(m, com, ixx, iyy, izz, ixy=0.0, ixz=0.0, iyz=0.0):
    return (
        f'<inertial><origin xyz="{com}" rpy="0.1 -0.2 0.3"/><mass value="{m}"/>'
        f'<inertia ixx="{ixx}" ixy="{ixy}" ixz="{ixz}" iyy="{iyy}" iyz="{iyz}" izz="{izz}"/></inertial>'
    )


def _link(name, *inertial):
    return f'<link name="{name}">{_inertial(*inertial) if inertial else ""}</link>'


def _joint(name, jtype, parent, child, xyz, rpy="0 0 0", axis=None):
    ax = "" if axis is None else f'<axis xyz="{axis}"/>'
    return (
        f'<joint name="{name}" type="{jtype}"><parent link="{parent}"/><child link="{child}"/>'
        f'<origin xyz="{xyz}" rpy="{rpy}"/>{ax}<limit lower="-2" upper="2" effort="50" velocity="3"/></joint>'
    )


#: A branched robot written for this test (the project's own; licence: the project's): a waist
#: on the ground carrying a torso; on the torso a left arm (its shoulder on a mount welded to
#: the torso, a hand welded to the forearm), a right arm ending in a prismatic finger, a head;
#: and a second arm on the ground. Inertias with products of inertia and rotated principal axes,
#: joints with rolled origins and tilted axes.
TREE = (
    '<robot name="branched">'
    + _link("world")
    + _link("torso", 4.0, "0.01 0.0 0.15", 0.12, 0.10, 0.05, 0.004, -0.003, 0.002)
    + _link("left_mount", 0.3, "0 0.02 0", 2e-4, 3e-4, 2e-4)
    + _link("left_upper", 1.2, "0.2 0 0.01", 2e-3, 1.6e-2, 1.6e-2, 1e-4)
    + _link("left_fore", 0.8, "0.15 0.01 0", 1e-3, 6e-3, 6e-3, 0.0, 2e-4)
    + _link("left_hand", 0.2, "0.03 0 0", 1e-4, 1e-4, 1e-4)
    + _link("right_upper", 1.0, "0.15 0 0", 1.5e-3, 9e-3, 9e-3)
    + _link("right_fore", 0.6, "0.1 0 0.01", 8e-4, 3e-3, 3e-3, 1e-4, 0.0, -1e-4)
    + _link("right_finger", 0.1, "0.02 0 0", 1e-5, 2e-5, 2e-5)
    + _link("head", 0.5, "0 0 0.05", 2e-3, 2e-3, 1.5e-3)
    + _link("side", 0.6, "0 0.1 0", 3e-3, 1e-3, 3e-3)
    + _link("camera")
    + _joint("waist", "revolute", "world", "torso", "0 0 0.3", "0 0 0.2", "0 0 1")
    + _joint("left_mount_fix", "fixed", "torso", "left_mount", "0 0.15 0.35", "0.3 0 0")
    + _joint("left_shoulder", "revolute", "left_mount", "left_upper", "0 0.05 0", "0 0 0.1", "0 1 0")
    + _joint("left_elbow", "revolute", "left_upper", "left_fore", "0.4 0 0", axis="0 1 0")
    + _joint("left_wrist_fix", "fixed", "left_fore", "left_hand", "0.3 0 0")
    + _joint("right_shoulder", "revolute", "torso", "right_upper", "0 -0.15 0.35", "-0.3 0.1 0", "0.2 1 0")
    + _joint("right_elbow", "continuous", "right_upper", "right_fore", "0.35 0 0.02", axis="0 0 1")
    + _joint("right_slide", "prismatic", "right_fore", "right_finger", "0.25 0 0", axis="1 0 0")
    + _joint("neck", "revolute", "torso", "head", "0 0 0.5", axis="0 1 0")
    + _joint("camera_fix", "fixed", "head", "camera", "0.05 0 0.1")
    + _joint("side_hinge", "revolute", "world", "side", "0.5 0 0.1", axis="1 0 0")
    + "</robot>"
)
LEAVES = ("left_fore", "right_fore", "head", "side")
TUBE = {"section": {"tube": {"outer_diameter": 0.04, "wall": 0.003}}, "material": "aluminium"}
FLEX = {"left_upper": {**TUBE, "keep_inertia": True}, "right_upper": {**TUBE, "keep_inertia": False}}


def _pin_tree(src, lock=()):
    """Pinocchio's model of the unmodified URDF (text or file), the joints in ``lock`` removed at
    zero by ``pin.buildReducedModel``."""
    pin = pytest.importorskip("pinocchio")
    from dttmm.urdf_import import resolve_urdf

    if src.lstrip().startswith("<"):
        model = pin.buildModelFromXML(src)
    else:
        model = pin.buildModelFromUrdf(str(resolve_urdf(src)))
    if lock:
        model = pin.buildReducedModel(model, [model.getJointId(n) for n in lock], pin.neutral(model))
    return model


def _pin_state(model, names, q, v, tau):
    """Pinocchio's configuration, velocity and torque vectors of the joint values given in the
    order of ``names`` (a continuous joint's configuration is (cos, sin) there)."""
    import pinocchio as pin

    qp, vp, tp = pin.neutral(model), np.zeros(model.nv), np.zeros(model.nv)
    for name, a, w, t in zip(names, q, v, tau):
        j = model.getJointId(name)
        iq, iv = model.idx_qs[j], model.idx_vs[j]
        qp[iq : iq + model.nqs[j]] = (np.cos(a), np.sin(a)) if model.nqs[j] == 2 else a
        vp[iv], tp[iv] = w, t
    return qp, vp, tp


def _torque_case(arm, amplitude=1.0):
    n = len(arm.joints)
    return arm.case(Scenario(1.0, 0.1, tuple(Drive("torque", Sine(0.0, amplitude)) for _ in range(n))))


# ------------------------------------------------------------------ the import ----------------
def test_tree_follows_the_urdf():
    """Each moving body hangs on the body of its URDF parent (through fixed joints: the left
    shoulder's origin is composed through the welded mount), two moving joints on the ground hang
    on the base, the model links take the URDF names, the tool is the end-effector, the locked
    prismatic finger's mass merges into the right forearm."""
    from dttmm.spatial.rotation import rpy_matrix

    arm = read_urdf(TREE, lock=["right_slide"], tool="left_hand")
    m = arm.model
    assert arm.joints == (
        "waist",
        "left_shoulder",
        "left_elbow",
        "right_shoulder",
        "right_elbow",
        "neck",
        "side_hinge",
    )
    assert m.link_names == (
        "torso",
        "left_upper",
        "left_fore",
        "right_upper",
        "right_fore",
        "head",
        "side",
        "left_hand",
    )
    assert m.parents == (-1, 0, 1, 0, 3, 0, -1, 2)
    assert m.end_effector == "left_hand" and m.leaves == (4, 5, 6, 7)
    assert m.links[0].parent == "base" and m.links[6].parent == "base"
    shoulder = m.links[1].joint
    mount = rpy_matrix((0.3, 0.0, 0.0))
    assert np.allclose(
        shoulder.origin_xyz, np.array([0.0, 0.15, 0.35]) + mount @ [0.0, 0.05, 0.0], atol=1e-15
    )
    assert np.allclose(rpy_matrix(shoulder.origin_rpy), mount @ rpy_matrix((0.0, 0.0, 0.1)), atol=1e-15)
    assert m.links[4].beam.mass == pytest.approx(0.7, abs=1e-15)  # forearm 0.6 + finger 0.1
    # the tool welded to the left forearm: a massless locked link reaching the hand's origin
    assert m.links[7].joint.locked and m.links[7].beam.length == pytest.approx(0.3)
    # a leaf's own link as the tool: its frame is the end-effector, no link added
    own = read_urdf(TREE, lock=["right_slide"], tool="head").model
    assert own.end_effector == "head" and own.n_links == 7


def test_flexible_links_on_branches():
    """The overlay on two branches: each beam runs from its joint to its one next joint (kept
    URDF body: a body link and the beam, named ``<link>.body`` and ``<link>``), the next joint
    hangs on the beam's tip."""
    arm = read_urdf(TREE, FLEX, lock=["right_slide"], tool="left_hand")
    m = arm.model
    assert m.link_names == (
        "torso",
        "left_upper.body",
        "left_upper",
        "left_fore",
        "right_upper",
        "right_fore",
        "head",
        "side",
        "left_hand",
    )
    assert m.parents == (-1, 0, 1, 2, 0, 4, 0, -1, 3)
    assert arm.links[1:3] == ("left_upper", "left_upper")
    assert m.links[2].beam.length == pytest.approx(0.4) and not m.links[2].rigid
    assert m.links[4].beam.length == pytest.approx(np.hypot(0.35, 0.02)) and not m.links[4].rigid
    assert np.allclose(m.links[3].joint.origin_xyz, 0.0, atol=1e-15)  # the elbow on the beam's tip


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        (
            {"lock": ["right_slide"]},
            r"^tool = None: must name the end-effector: the tree has 4 leaves "
            r"\(left_fore, right_fore, head, side\)",
        ),
        ({"tool": "left_mount"}, r"^tool = 'left_mount': is on 'torso', which carries moving joints"),
        ({"tool": "world"}, r"^tool = 'world': does not move"),
        ({"tool": "left_hnd"}, r"^tool = 'left_hnd': is not a link of the URDF \(did you mean 'left_hand'"),
        ({"tool": "head", "lock": []}, r"^joint 'right_slide'\.type = 'prismatic': is not supported"),
        (
            {"tool": "head", "lock": ["right_slide"], "flexible": {"side": {**TUBE, "keep_inertia": True}}},
            r"^flexible\.side = 'side': is a leaf of the tree",
        ),
        (
            {"tool": "head", "lock": ["right_slide"], "flexible": {"torso": {**TUBE, "keep_inertia": True}}},
            r"^flexible\.torso = 'torso': carries 3 moving joints \(left_shoulder, right_shoulder, neck\)",
        ),
    ],
    ids=[
        "no-tool",
        "tool-inner",
        "tool-ground",
        "tool-typo",
        "prismatic",
        "flexible-leaf",
        "flexible-branch-point",
    ],
)
def test_tree_refusals_are_one_line(kwargs, match):
    with pytest.raises(dttmm.InputError, match=match) as err:
        read_urdf(TREE, **{"lock": ["right_slide"], **kwargs})
    assert "\n" not in str(err.value)


def test_tree_case_file(tmp_path):
    """A case file naming a branched URDF beside it, with ``lock``, ``tool`` and an overlay on a
    branch: loaded by ``dttmm.load_case``, one drive per moving joint in the import's order."""
    (tmp_path / "tree.urdf").write_text(TREE)
    drives = "".join(
        '[[scenario.drives]]\nkind = "torque"\nlaw = "constant"\nvalue = 0.0\n' for _ in range(7)
    )
    (tmp_path / "tree.toml").write_text(
        'kind = "spatial"\n[model]\nurdf = "tree.urdf"\nlock = ["right_slide"]\ntool = "left_hand"\n'
        "[model.flexible.right_upper]\nsection = { tube = { outer_diameter = 0.04, wall = 0.003 } }\n"
        'material = "aluminium"\nkeep_inertia = false\n'
        f"[scenario]\nduration = 0.1\noutput_step = 0.01\n{drives}"
    )
    case = dttmm.load_case(tmp_path / "tree.toml")
    assert case.model.end_effector == "left_hand" and case.provenance["flexible"] == ["right_upper"]
    assert not case.model.links[case.model.link_index("right_upper")].rigid
    doc = {
        "model": {"urdf": "tree.urdf", "lock": ["right_slide"]},
        "scenario": {"duration": 0.1, "output_step": 0.01, "drives": []},
    }
    with pytest.raises(dttmm.InputError, match=r"^tool = None: must name the end-effector"):
        case_from_urdf_dict(doc, tmp_path)


# ------------------------------------------------------------------ the rigid tree ------------
def _aba_gap(src, lock, tool, seed, engines=("python", "numba")):
    """max |q̈ − pin.aba| / max |pin.aba| over random states and torques (gravity on)."""
    pin = pytest.importorskip("pinocchio")
    arm = read_urdf(src, lock=lock, tool=tool)
    model = _pin_tree(src, lock)
    data = model.createData()
    n = len(arm.joints)
    assert model.nv == n
    case = _torque_case(arm)
    rng = np.random.default_rng(seed)
    worst = 0.0
    for _ in range(3):
        q, v, tau = rng.normal(size=n), rng.normal(size=n), rng.normal(size=n)
        ref = pin.aba(model, data, *_pin_state(model, arm.joints, q, v, tau))
        ref = ref[[model.idx_vs[model.getJointId(j)] for j in arm.joints]]
        for engine in engines:
            qdd = sp.accelerations(case, 1, q, v, 0.0, forces=tau, engine=engine)
            worst = max(worst, np.max(np.abs(qdd - ref)) / np.max(np.abs(ref)))
    return worst


def test_rigid_tree_is_pinocchios_urdf():
    """Every link rigid: the DT-TMM's q̈ (tree sweep, compiled and uncompiled) = ``pin.aba`` of the
    model Pinocchio builds from the same URDF text (its own tree; the prismatic finger removed
    at zero by ``pin.buildReducedModel``), at random states and torques, gravity on (measured
    5.1e-16 relative)."""
    assert _aba_gap(TREE, ["right_slide"], "left_hand", 1) < 1e-12


def _robots():
    from importlib import metadata

    try:
        metadata.distribution("example-robot-data")
    except metadata.PackageNotFoundError:
        pytest.skip("example-robot-data is not installed (pip install 'dttmm[robots]')")


@pytest.mark.parametrize(
    ("src", "lock", "tool"),
    [
        (ALLEGRO, (), "link_15.0_tip"),
        (
            BAXTER,
            (
                "l_gripper_l_finger_joint",
                "l_gripper_r_finger_joint",
                "r_gripper_l_finger_joint",
                "r_gripper_r_finger_joint",
            ),
            "left_gripper",
        ),
    ],
    ids=["allegro-hand", "baxter"],
)
def test_branched_robot_is_pinocchios_urdf(src, lock, tool):
    """Real branched robots of example-robot-data, every link rigid: the Allegro hand (16 revolute
    joints, four fingers on the palm) and Baxter (a dual-arm robot with a head pan, 15 revolute
    joints; the prismatic gripper fingers locked): q̈ = ``pin.aba`` of Pinocchio's model of the
    unmodified URDF (fingers removed at zero by ``pin.buildReducedModel``) at random states and
    torques (measured 3.5e-16 and 6.5e-16 relative)."""
    _robots()
    assert _aba_gap(src, lock, tool, 2) < 1e-12


# ------------------------------------------------------------------ a flexible branch ---------
def _flexible_case(drives, duration, output_step, damping=0.0):
    """The test's tree with the left upper arm (its URDF body kept) and the right upper arm (its
    URDF body replaced) aluminium tubes, the finger locked, the tool at the left hand."""
    flex = {k: {**v, "damping": damping} for k, v in FLEX.items()}
    arm = read_urdf(TREE, flex, lock=["right_slide"], tool="left_hand")
    return arm.case(Scenario(duration, output_step, drives))


def test_flexible_branches_equal_the_global_solver():
    """Torques on every joint under gravity, k = 2, Newmark, h = 1e-3, 0.05 s: the DT-TMM's tree
    sweep = the spatial global solver (its own frame recursion over the tree and mass matrix):
    link tips ≤ 1e-9 m (measured 1.1e-16 m, joint angles 1e-16 rad; the beams bend by up to
    0.026 mm, the joints turn by up to 0.15 rad)."""
    from reference_models import spatial_global as sg

    drives = tuple(
        Drive("torque", Sine(a, 9.0 + i)) for i, a in enumerate((3.0, 2.0, -1.0, 1.5, 0.5, 0.3, 1.0))
    )
    case = _flexible_case(drives, 0.05, 0.01)
    kw = dict(elements_per_link=2, h=1e-3)
    r, g = sp.simulate(case, **kw), sg.simulate(case, **kw)
    assert r.success and g.success
    assert np.max(np.abs(r.link_tip - g.link_tip)) <= 1e-9
    assert np.max(np.abs(r.end_effector - g.end_effector)) <= 1e-9
    flex = [i for i, lk in enumerate(case.model.links) if not lk.rigid]
    assert np.max(np.abs(r.tip_deflection[:, flex])) > 1e-5  # the beams bend
    assert np.max(np.abs(r.joint_angle - r.joint_angle[0])) > 1e-3  # the joints turn


def test_static_sag_of_a_branch_against_the_exudyn_peer():
    """The tree held at its zero pose (motion drives) under gravity: the DT-TMM's rest state (the
    damped beams released at t = 0 and run to rest, 0.4 s, k = 4, h = 1e-3; the DT-TMM's statics
    take chains only) against the static equilibrium of Exudyn's 3-D geometrically exact beam
    with its rigid bodies (``reference_models.exudyn_beam3d``, undamped: damping does not move
    an equilibrium) at k = 2, 4: every link tip converges to the DT-TMM's at second order
    (measured 3.2e-6, 7.9e-7 m at k = 2, 4, and 2.0e-7 m at k = 8; the left hand sags
    0.21 mm)."""
    pytest.importorskip("exudyn")
    from reference_models import exudyn_beam3d as xb

    held = tuple(Drive("motion", Constant(0.0)) for _ in range(7))
    res = sp.simulate(_flexible_case(held, 0.4, 0.01, damping=4e-3), elements_per_link=4, h=1e-3)
    assert res.success
    rest = res.link_tip[-1]
    assert np.max(np.abs(res.link_tip[-1] - res.link_tip[-2])) < 1e-12  # at rest
    case = _flexible_case(held, 0.4, 0.01)
    tips = [xb.statics(case, elements_per_link=k, load_steps=1)["link_tip"] for k in (2, 4)]
    gaps = [np.max(np.linalg.norm(t - rest, axis=1)) for t in tips]
    assert np.linalg.norm(res.end_effector[0] - res.end_effector[-1]) > 1e-4  # the hand sags
    assert gaps[0] < 1e-5 and 3.0 < gaps[0] / gaps[1] < 5.0, gaps


def test_tree_statics_is_the_rest_state():
    """The DT-TMM's statics on a tree (the loads gathered from every branch to the base) at the
    tree's zero pose under gravity, k = 4: every link tip at the rest state of the damped
    dynamic run (the same discrete equations reached by the time loop's sweeps: measured
    3.8e-13 m, the hand sagging 0.21 mm); the end-effector's tip is the tool's (9.6e-14 m)."""
    held = tuple(Drive("motion", Constant(0.0)) for _ in range(7))
    res = sp.simulate(_flexible_case(held, 0.4, 0.01, damping=4e-3), elements_per_link=4, h=1e-3)
    assert res.success and np.max(np.abs(res.link_tip[-1] - res.link_tip[-2])) < 1e-12
    st = sp.statics(_flexible_case(held, 0.4, 0.01), elements_per_link=4)
    assert st.link_tips.shape == res.link_tip[-1].shape
    assert np.max(np.linalg.norm(st.link_tips - res.link_tip[-1], axis=1)) < 1e-9
    assert np.linalg.norm(st.tip_position - res.end_effector[-1]) < 1e-9
    assert np.linalg.norm(res.end_effector[0] - st.tip_position) > 1e-4  # the hand sags


def test_docs_snippet_runs():
    """The snippet of docs/urdf.md "Branched robots" runs as written (Baxter with a flexible
    upper arm on the left branch): the end-effector is the left gripper, every link has a tip."""
    _robots()
    from pathlib import Path

    text = (Path(__file__).resolve().parents[1] / "docs" / "urdf.md").read_text()
    block = text.split("## Branched robots", 1)[1].split("```python\n", 1)[1].split("```", 1)[0]
    ns: dict = {"print": lambda *a: None}
    exec(compile(block, "docs/urdf.md", "exec"), ns)
    res, model = ns["res"], ns["model"]
    assert model.end_effector == "left_gripper" and res.success
    assert res.link_tip.shape[1] == model.n_links == 17
    assert np.all(np.isfinite(res.end_effector))
    flex = model.link_index("left_upper_elbow")
    assert not model.links[flex].rigid and np.max(np.abs(res.tip_deflection[:, flex])) > 0.0
