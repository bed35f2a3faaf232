"""A robot from its URDF (dttmm/urdf_import.py, dttmm/sections.py; docs/urdf.md): refusals,
the section calculator against hand formulas, the all-rigid import of the UR5 and the Panda of
example-robot-data against Pinocchio's own reading of the unmodified URDF (ABA at random states,
trajectories over 1 s), the flexible-link overlay's geometry and inertia against Pinocchio's
model with the beam added by hand, the stiff limit (gap ∝ 1/stiffness), the tool point's sag
under gravity against the cantilever's closed form, and the shipped robot cases."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest

import dttmm
import dttmm.spatial as sp
from dttmm import Drive, Scenario, Sine
from dttmm.sections import section_properties
from dttmm.urdf_import import case_from_urdf_dict, matrix_rpy, read_urdf

ROOT = Path(__file__).resolve().parents[1]
ROBOTS = ROOT / "experiments" / "cases" / "spatial" / "robots"
UR5 = "example-robot-data:ur_description/urdf/ur5_robot.urdf"
PANDA = "example-robot-data:panda_description/urdf/panda.urdf"
FINGERS = ("panda_finger_joint1", "panda_finger_joint2")
ALU = (68.9e9, 26.0e9, 2700.0)  # E, G, rho of 6061-T6 (ASM data sheet)


def _robots():
    """Skip unless example-robot-data (the URDFs) is installed."""
    from importlib import metadata

    try:
        metadata.distribution("example-robot-data")
    except metadata.PackageNotFoundError:
        pytest.skip("example-robot-data is not installed (pip install 'dttmm[robots]')")


def _pin_model(src, lock=()):
    """Pinocchio's model of the unmodified URDF (``pin.buildModelFromUrdf``), the joints in
    ``lock`` removed at zero by ``pin.buildReducedModel``."""
    pin = pytest.importorskip("pinocchio")
    from dttmm.urdf_import import resolve_urdf

    model = pin.buildModelFromUrdf(str(resolve_urdf(src)))
    if lock:
        ids = [model.getJointId(n) for n in lock]
        model = pin.buildReducedModel(model, ids, pin.neutral(model))
    return model


# ------------------------------------------------------------------ small URDF texts ----------
def _urdf(joints: str, links: str = "", bare=("base",)) -> str:
    """A URDF of the links base, a, b, c that ``joints`` name (those in ``bare`` without
    ``<inertial>``), the extra ``links`` and the ``joints``."""
    inertial = (
        '<inertial><origin xyz="0.1 0 0" rpy="0 0 0"/><mass value="1.0"/>'
        '<inertia ixx="1e-3" ixy="0" ixz="0" iyy="2e-3" iyz="0" izz="2e-3"/></inertial>'
    )
    names = [n for n in ("base", "a", "b", "c") if f'link="{n}"' in joints]
    body = "".join(f'<link name="{n}">{inertial if n not in bare else ""}</link>' for n in names)
    return f'<robot name="t">{body}{links}{joints}</robot>'


def _joint(name, jtype, parent, child, xyz="0 0 0.2", extra='<axis xyz="0 1 0"/>'):
    return (
        f'<joint name="{name}" type="{jtype}"><parent link="{parent}"/><child link="{child}"/>'
        f'<origin xyz="{xyz}" rpy="0 0 0"/>{extra}</joint>'
    )


CHAIN = _joint("j1", "revolute", "base", "a") + _joint("j2", "revolute", "a", "b")


def test_small_chain_reads():
    """Two revolute joints, a continuous one and a fixed one: three moving bodies; the fixed
    child's mass merges into its parent; the limits are kept."""
    text = _urdf(
        CHAIN.replace(
            '<axis xyz="0 1 0"/></joint>', '<axis xyz="0 1 0"/><limit effort="7" velocity="2"/></joint>', 1
        )
        + _joint("j3", "continuous", "b", "c", extra="")
        + _joint("f", "fixed", "c", "d"),
        links='<link name="d"><inertial><mass value="0.5"/><origin xyz="0 0 0.1"/></inertial></link>',
    )
    arm = read_urdf(text)
    assert arm.joints == ("j1", "j2", "j3")
    assert arm.model.links[2].joint.axis == (1.0, 0.0, 0.0)  # URDF's default axis
    c = arm.model.links[2].beam
    assert c.mass == 1.5 and np.allclose(
        c.com, [0.1 / 1.5, 0.0, (0.2 + 0.1) * 0.5 / 1.5]
    )  # d at the origin 0.2 + 0.1
    assert arm.limits[0].effort == 7.0 and arm.limits[0].lower is None
    assert arm.provenance()["limits"]["j1"] == {"velocity": 2.0, "effort": 7.0}


@pytest.mark.parametrize(
    ("text", "match"),
    [
        (
            _urdf(CHAIN + _joint("slide", "prismatic", "b", "c")),
            r"^joint 'slide'\.type = 'prismatic': is not supported",
        ),
        (
            _urdf(CHAIN, bare=("base", "a")),
            r"^link 'a'\.inertial = None: is missing",
        ),
        (_urdf(CHAIN + _joint("loop", "revolute", "base", "b")), r"^link 'b' = .*two parents"),
        (
            _urdf(CHAIN + _joint("j3", "revolute", "a", "c")),
            r"^tool = None: must name the end-effector: the tree has 2 leaves \(b, c\)",
        ),
        (_urdf(CHAIN + _joint("j3", "planar", "b", "c")), r"^joint 'j3'\.type = 'planar'"),
        (_urdf(CHAIN + _joint("j3", "floating", "b", "c")), r"^joint 'j3'\.type = 'floating'"),
        (_urdf(CHAIN.replace('xyz="0 0 0.2"', 'xyz="0 0.2"', 1)), r"^joint 'j1'\.origin\.xyz = '0 0\.2'"),
        (_urdf(CHAIN + _joint("j3", "revolute", "b", "nowhere")), r"^joint 'j3'\.child = 'nowhere'"),
    ],
    ids=["prismatic", "no-inertial", "two-parents", "branched", "planar", "floating", "origin", "child"],
)
def test_refusals_are_one_line(text, match):
    with pytest.raises(dttmm.InputError, match=match) as err:
        read_urdf(text)
    assert "\n" not in str(err.value)


def test_missing_inertial_on_a_welded_link_is_a_marker():
    """A link on a fixed joint without ``<inertial>`` (a tool frame) is a massless marker."""
    text = _urdf(CHAIN + _joint("tool_joint", "fixed", "b", "tool"), links='<link name="tool"/>')
    arm = read_urdf(text, tool="tool")
    assert arm.model.links[-1].joint.locked and arm.model.links[-1].beam.length == pytest.approx(0.2)


def test_lock_holds_a_prismatic_joint():
    text = _urdf(CHAIN + _joint("slide", "prismatic", "b", "c"))
    arm = read_urdf(text, lock=["slide"])
    assert arm.joints == ("j1", "j2") and arm.model.links[-1].beam.mass == 2.0
    with pytest.raises(
        dttmm.InputError, match=r"^lock = 'slid': is not a joint of the URDF \(did you mean 'slide'"
    ):
        read_urdf(text, lock=["slid"])


@pytest.mark.parametrize(
    ("flexible", "match"),
    [
        (
            {"aa": {"keep_inertia": True}},
            r"^flexible\.aa = 'aa': is not a link of the URDF \(did you mean 'a'",
        ),
        ({"b": {"keep_inertia": True}}, r"^flexible\.b = 'b': is the last moving link"),
        ({"a": {"keep_inertias": True}}, r"^flexible\.a\.keep_inertias = True: unknown key.*keep_inertia"),
        (
            {"a": {"keep_inertia": True, "section": {"tube": {"outer_diameter": 0.02, "wall": 0.002}}}},
            r"material.*required",
        ),
        (
            {
                "a": {
                    "keep_inertia": True,
                    "section": {"tube": {"outer_diameter": 0.02, "wall": 0.01}},
                    "material": "steel",
                }
            },
            r"^flexible\.a\.section\.tube\.wall = 0\.01: must be less than the outer radius",
        ),
        (
            {
                "a": {
                    "keep_inertia": False,
                    "section": {"tube": {"outer_diameter": 0.02, "wall": 0.002}},
                    "material": "brass",
                }
            },
            r"^flexible\.a\.material = 'brass': is not a known material",
        ),
        ({"a": {"keep_inertia": False, "GJ": 1.0}}, r"^flexible\.a\.EIy = None: is required"),
    ],
    ids=["unknown-link", "last-link", "unknown-key", "no-material", "wall", "material", "beam-data"],
)
def test_overlay_refusals(flexible, match):
    with pytest.raises(dttmm.InputError, match=match) as err:
        read_urdf(_urdf(CHAIN), flexible)
    assert "\n" not in str(err.value)


def test_matrix_rpy_round_trip():
    rng = np.random.default_rng(3)
    from dttmm.spatial.rotation import rpy_matrix

    for rpy in [*rng.uniform(-3, 3, size=(20, 3)), (0.3, math.pi / 2, -0.2), (0.0, -math.pi / 2, 1.0)]:
        r = rpy_matrix(rpy)
        assert np.max(np.abs(rpy_matrix(matrix_rpy(r)) - r)) < 1e-15


# ------------------------------------------------------------------ sections ------------------
def test_section_calculator_against_hand_formulas():
    """Tube, solid and hollow rectangle, I-beam: the areas and second moments worked by hand
    (not by the calculator's formulas): a 40 × 20 mm rectangle has Iy = 0.02·0.04³/12 about
    the axis across its height, Iz = 0.04·0.02³/12; its torsion constant from Roark's table
    (a/b = 2: J = 0.229 a b³ with β = 0.229 tabulated, ~0.5 % from the formula)."""
    E, G, rho = 210e9, 81e9, 7850.0
    t = section_properties({"tube": {"outer_diameter": 0.05, "wall": 0.005}}, "steel")
    i_tube = math.pi / 64 * (0.05**4 - 0.04**4)
    assert t["EIy"] == pytest.approx(E * i_tube, rel=1e-12) and t["EIz"] == t["EIy"]
    assert t["GJ"] == pytest.approx(G * 2 * i_tube, rel=1e-12)
    assert t["rhoA"] == pytest.approx(rho * math.pi / 4 * (0.05**2 - 0.04**2), rel=1e-12)
    assert t["rhoJ"] == pytest.approx(rho * 2 * i_tube, rel=1e-12)
    r = section_properties({"rectangle": {"width": 0.02, "height": 0.04}}, {"E": E, "nu": 0.3, "rho": rho})
    assert r["EIy"] == pytest.approx(E * 0.02 * 0.04**3 / 12, rel=1e-12)
    assert r["EIz"] == pytest.approx(E * 0.04 * 0.02**3 / 12, rel=1e-12)
    assert r["GJ"] == pytest.approx(E / 2.6 * 0.229 * 0.04 * 0.02**3, rel=6e-3)
    h = section_properties({"rectangle": {"width": 0.05, "height": 0.05, "wall": 0.005}}, "aluminium")
    assert h["rhoA"] == pytest.approx(2700 * (0.05**2 - 0.04**2), rel=1e-12)
    # thin-walled square box (Bredt): J = t·b_m³ for a square of mid-line side b_m
    assert h["GJ"] == pytest.approx(26e9 * 0.005 * 0.045**3, rel=1e-12)
    ib = section_properties({"i_beam": {"width": 0.1, "height": 0.2, "flange": 0.01, "web": 0.006}}, "steel")
    iy = 2 * (0.1 * 0.01**3 / 12 + 0.1 * 0.01 * 0.095**2) + 0.006 * 0.18**3 / 12  # parallel axes
    assert ib["EIy"] == pytest.approx(E * iy, rel=1e-12)
    assert ib["rhoA"] == pytest.approx(rho * (2 * 0.1 * 0.01 + 0.18 * 0.006), rel=1e-12)


# ------------------------------------------------------------------ the rigid limit -----------
@pytest.mark.parametrize(("src", "lock"), [(UR5, ()), (PANDA, FINGERS)], ids=["ur5", "panda"])
def test_rigid_import_is_pinocchios_urdf(src, lock):
    """Every link rigid: the DT-TMM's q̈ (compiled and uncompiled) = ``pin.aba`` of the model
    Pinocchio builds from the unmodified URDF (the Panda's fingers locked there by
    ``pin.buildReducedModel``), at random states and torques, gravity included."""
    _robots()
    pin = pytest.importorskip("pinocchio")
    arm = read_urdf(src, lock=lock)
    model = _pin_model(src, lock)
    data = model.createData()
    n = len(arm.joints)
    assert model.nq == model.nv == n
    case = arm.case(Scenario(1.0, 0.1, tuple(Drive("torque", Sine(0.0, 1.0)) for _ in range(n))))
    rng = np.random.default_rng(1)
    for _ in range(3):
        q, v, tau = 1.5 * rng.normal(size=n), rng.normal(size=n), 10 * rng.normal(size=n)
        ref = pin.aba(model, data, q, v, tau)
        for engine in ("python", "numba"):
            qdd = sp.accelerations(case, 1, q, v, 0.0, forces=tau, engine=engine)
            # measured ≤ 3.6e-14 rad/s² (|q̈| up to 300)
            assert np.max(np.abs(qdd - ref)) < 1e-12 * max(1.0, np.max(np.abs(ref)))


def _torques(n, scale):
    return tuple(Drive("torque", Sine(a, 0.7 + 0.3 * i, phase=0.4 * i)) for i, a in enumerate(scale[:n]))


@pytest.mark.parametrize(
    ("src", "lock", "scale", "gravity"),
    [
        (UR5, (), (20.0, 60.0, 25.0, 4.0, 2.0, 0.5), -9.81),
        (PANDA, FINGERS, (5.0, 10.0, 2.0, 5.0, 0.1, 0.1, 0.02), 0.0),
    ],
    ids=["ur5", "panda"],
)
def test_rigid_trajectory_against_pinocchio(src, lock, scale, gravity):
    """Every link rigid, under smooth torques for 1 s: the DT-TMM by RK4 at h = 2.5e-4 against
    ``pin.aba`` of the unmodified URDF integrated by SciPy's DOP853 (rtol 1e-13): joint angles
    within 1e-8 rad (measured: UR5 under gravity 4.0e-11 rad, its joints turning by up to
    5.8 rad; Panda 3.3e-11 rad, up to 6.6 rad — without gravity: standing upright the Panda
    falls under any open-loop torques within the second and its light wrist whirls; gravity is
    in the ABA test above)."""
    _robots()
    pin = pytest.importorskip("pinocchio")
    from scipy.integrate import solve_ivp

    arm = read_urdf(src, lock=lock, gravity=(0.0, 0.0, gravity))
    n = len(arm.joints)
    case = arm.case(Scenario(1.0, 0.01, _torques(n, scale)))
    model = _pin_model(src, lock)
    model.gravity.linear = np.array([0.0, 0.0, gravity])
    data = model.createData()
    drives = case.scenario.drives

    def f(t, y):
        tau = np.array([d.torque(t, False) for d in drives])
        return np.concatenate([y[n:], pin.aba(model, data, y[:n], y[n:], tau)])

    t_out = case.scenario.output_times
    sol = solve_ivp(f, (0.0, 1.0), np.zeros(2 * n), method="DOP853", rtol=1e-13, atol=1e-14, t_eval=t_out)
    res = sp.simulate(case, elements_per_link=1, h=2.5e-4, integrator="rk4")
    assert res.success
    assert np.max(np.abs(sol.y[:n].T)) > 2.0
    gap = np.max(np.abs(res.joint_angle - sol.y[:n].T))
    assert gap < 1e-8
    assert np.max(np.abs(res.joint_rate - sol.y[n:].T)) < 1e-7


# ------------------------------------------------------------------ the flexible overlay -------
TUBE = {"tube": {"outer_diameter": 0.085, "wall": 0.004}}


@pytest.mark.parametrize("keep", [True, False])
def test_overlay_geometry_and_inertia_against_pinocchio(keep):
    """The UR5 with its upper arm and forearm tubes (consecutive flexible links, each from its
    joint to the next one): the rigid limit of the overlaid arm (``reference_models.
    pinocchio_spatial`` builds it, each beam a rigid rod) has the joint placements and the tool
    point of Pinocchio's URDF model at random angles, and its forward dynamics is ``pin.aba`` of
    the URDF model whose two bodies have their rod added (keep_inertia) or replaced by it, each
    rod computed here from the URDF's next-joint origin d: mass ρA|d| at d/2, inertia about it
    m|d|²/12 (I − d̂d̂ᵀ) + |d| ρI (I + d̂d̂ᵀ) (a tube)."""
    _robots()
    pin = pytest.importorskip("pinocchio")
    from reference_models import pinocchio_spatial as ps

    overlay = {"section": TUBE, "material": "aluminium", "keep_inertia": keep}
    arm = read_urdf(UR5, {"upper_arm_link": overlay, "forearm_link": overlay}, tool="tool0")
    case = arm.case(Scenario(1.0, 0.1, tuple(Drive("torque", Sine(0.0, 1.0)) for _ in range(6))))
    mine = ps.build_model(case.model)
    ref = _pin_model(UR5)
    ro, ri = 0.0425, 0.0385
    rho_i = ALU[2] * math.pi / 4 * (ro**4 - ri**4)
    for body, nxt in (("shoulder_lift_joint", "elbow_joint"), ("elbow_joint", "wrist_1_joint")):
        d = ref.jointPlacements[ref.getJointId(nxt)].translation.copy()
        L = np.linalg.norm(d)
        u = d / L
        m = ALU[2] * math.pi * (ro**2 - ri**2) * L
        rod = pin.Inertia(
            m, d / 2, m * L * L / 12 * (np.eye(3) - np.outer(u, u)) + L * rho_i * (np.eye(3) + np.outer(u, u))
        )
        jid = ref.getJointId(body)
        ref.inertias[jid] = (ref.inertias[jid] + rod) if keep else rod
    dm, dr = mine.createData(), ref.createData()
    tool_mine, tool_ref = mine.getFrameId("tip"), ref.getFrameId("tool0")
    rng = np.random.default_rng(4)
    for _ in range(3):
        q, v, tau = rng.normal(size=6), rng.normal(size=6), 10 * rng.normal(size=6)
        pin.framesForwardKinematics(mine, dm, q)
        pin.framesForwardKinematics(ref, dr, q)
        for j in range(1, 7):
            assert np.max(np.abs(dm.oMi[j].translation - dr.oMi[j].translation)) < 1e-14
        assert np.max(np.abs(dm.oMf[tool_mine].translation - dr.oMf[tool_ref].translation)) < 1e-14
        ref_a = pin.aba(ref, dr, q, v, tau)
        assert np.max(np.abs(pin.aba(mine, dm, q, v, tau) - ref_a)) < 1e-12 * np.max(np.abs(ref_a))


def _stiffened(case, factor):
    links = tuple(
        lk
        if lk.rigid
        else dataclasses.replace(
            lk,
            beam=dataclasses.replace(
                lk.beam,
                EA=lk.beam.EA * factor,
                GJ=lk.beam.GJ * factor,
                EIy=lk.beam.EIy * factor,
                EIz=lk.beam.EIz * factor,
            ),
        )
        for lk in case.model.links
    )
    return dataclasses.replace(case, model=dataclasses.replace(case.model, links=links))


@pytest.mark.parametrize("name", ["ur5", "panda"])
def test_stiff_limit_gap_falls_as_one_over_stiffness(name):
    """The shipped robot cases (upper arm and forearm aluminium tubes, the pick-and-place
    motion), 0.5 s, DT-TMM Newmark k = 2, h = 1e-3, with every stiffness × 10 and × 100,
    against their rigid limit by Pinocchio (``reference_models.pinocchio_spatial``: the beams
    as rigid rods, the same prescribed joint motion): the tool point's gap falls as
    1/stiffness (measured, × 1, 10, 100, 1000: UR5 3.8e-4, 3.8e-5, 3.8e-6, 3.9e-7 m; Panda
    1.4e-4, 1.5e-5, 1.5e-6, 1.5e-7 m)."""
    _robots()
    pytest.importorskip("pinocchio")
    from reference_models import pinocchio_spatial as ps

    case = dttmm.load_case(ROBOTS / "ur5.toml")
    case = dataclasses.replace(
        case, scenario=dataclasses.replace(case.scenario, duration=0.5, output_step=0.01)
    )
    rigid = ps.simulate(case, h=1e-3, integrator="newmark")
    gaps = []
    for factor in (10.0, 100.0):
        res = sp.simulate(_stiffened(case, factor), elements_per_link=2, h=1e-3)
        assert res.success
        gaps.append(np.max(np.linalg.norm(res.end_effector - rigid.end_effector, axis=1)))
    assert 5e-7 < gaps[1] < gaps[0] < 1e-4
    assert 8.0 < gaps[0] / gaps[1] < 12.0, gaps


def test_tool_sag_under_gravity_against_the_cantilever():
    """The UR5 at its zero pose (the arm stretched out horizontally), the upper arm an aluminium
    tube (keep_inertia: the URDF body rides on the shoulder joint), everything else rigid,
    joints held: the tool point's sag = the closed form of a cantilever of length L (shoulder-
    lift joint to elbow joint) under its own weight w = ρA g, the weight W of everything
    outboard at its centre r (tip force W, tip moment about the bending axis, torque about the
    beam axis; masses and centres from Pinocchio's model of the URDF), carried to
    the tool point t by the tip's rotation: δ = wL⁴/8EI + WL³/3EI + M L²/2EI, θ = wL³/6EI +
    WL²/2EI + M L/EI, φ = T L/GJ; sag = δ − ((θ b̂ + φ x̂) × (t − tip))_z, worked by
    ``experiments.handchecks.tool_displacement`` (the shipped ur5.toml's upper-arm tube, the one
    here; ``dttmm validate`` checks every method with it) (measured: DT-TMM k = 4 0.132711 mm,
    hand check 0.132713 mm, 1.7e-5 apart relative)."""
    _robots()
    pytest.importorskip("pinocchio")
    arm = read_urdf(
        UR5,
        {"upper_arm_link": {"section": TUBE, "material": "aluminium", "keep_inertia": True}},
        tool="tool0",
    )
    case = arm.case(Scenario(1.0, 0.1, tuple(Drive("torque", Sine(0.0, 1.0)) for _ in range(6))))
    res = sp.statics(case, elements_per_link=4)
    rigid = sp.statics(read_urdf(UR5, tool="tool0").case(case.scenario), elements_per_link=1)
    sag = rigid.tip_position[2] - res.tip_position[2]

    # the hand check (experiments.handchecks): the same tube, its joint and the next from
    # Pinocchio's model of the URDF, the outboard bodies' weight and moment
    from experiments.handchecks import tool_displacement

    hand = tool_displacement("ur5")["sag"]
    assert hand > 5e-5  # about a tenth of a millimetre
    assert abs(sag - hand) < 1e-4 * hand, (sag, hand)


# ------------------------------------------------------------------ case files -----------------
@pytest.mark.parametrize("name", ["ur5", "panda"])
def test_shipped_robot_cases_load_and_run(name):
    """The shipped robot cases load (their URDF from example-robot-data), record the import in
    their provenance, and run a short stretch (Newmark, k = 2) in which the flexible links bend
    and the rigid ones do not."""
    _robots()
    case = dttmm.load_case(ROBOTS / f"{name}.toml")
    prov = case.provenance
    assert prov["urdf"].startswith("example-robot-data:") and len(prov["flexible"]) == 2
    assert len(prov["limits"]) == case.n_joints
    short = dataclasses.replace(
        case, scenario=dataclasses.replace(case.scenario, duration=0.1, output_step=0.01)
    )
    res = sp.simulate(short, elements_per_link=2, h=1e-3)
    assert res.success
    flex = [i for i, lk in enumerate(case.model.links) if not lk.rigid]
    assert len(flex) == 2 and np.max(np.abs(res.tip_deflection[:, flex])) > 1e-7
    rigid = [i for i, lk in enumerate(case.model.links) if lk.rigid]
    assert np.max(np.abs(res.tip_deflection[:, rigid])) < 1e-15


def _doc(**model):
    return {
        "kind": "spatial",
        "model": {"urdf": "arm.urdf", **model},
        "scenario": {
            "duration": 0.1,
            "output_step": 0.01,
            "drives": [{"kind": "torque", "law": "constant", "value": 0.0}] * 2,
        },
    }


def test_case_file_form(tmp_path):
    """A case file naming a URDF beside it, with an overlay: loaded by ``dttmm.load_case``;
    unknown keys refused with the nearest valid key; a wrong number of drives names the
    joints."""
    (tmp_path / "arm.urdf").write_text(_urdf(CHAIN))
    (tmp_path / "arm.toml").write_text(
        'kind = "spatial"\n[model]\nurdf = "arm.urdf"\n'
        "[model.flexible.a]\nsection = { tube = { outer_diameter = 0.02, wall = 0.002 } }\n"
        'material = "steel"\nkeep_inertia = false\n'
        "[scenario]\nduration = 0.1\noutput_step = 0.01\n"
        '[[scenario.drives]]\nkind = "torque"\nlaw = "constant"\nvalue = 0.0\n'
        '[[scenario.drives]]\nkind = "torque"\nlaw = "constant"\nvalue = 0.0\n'
    )
    case = dttmm.load_case(tmp_path / "arm.toml")
    assert case.name == "arm" and case.model.gravity == (0.0, 0.0, -9.81)
    beam = case.model.links[0].beam
    assert isinstance(beam, sp.SpatialSection) and beam.length == pytest.approx(0.2)
    assert beam.EIz == pytest.approx(210e9 * math.pi / 64 * (0.02**4 - 0.016**4))
    assert dttmm.load_case(tmp_path / "arm.toml") == case  # the same file read again
    with pytest.raises(dttmm.InputError, match=r"^model\.flexibel = .*unknown key.*flexible"):
        case_from_urdf_dict(_doc(flexibel={}), tmp_path)
    with pytest.raises(
        dttmm.InputError, match=r"^model\.flexible\.a\.section\.tube\.outer_diam = .*outer_diameter"
    ):
        case_from_urdf_dict(
            _doc(
                flexible={
                    "a": {"keep_inertia": True, "section": {"tube": {"outer_diam": 0.02, "wall": 0.002}}}
                }
            ),
            tmp_path,
        )
    doc = _doc()
    doc["scenario"]["drives"] = doc["scenario"]["drives"][:1]
    with pytest.raises(
        dttmm.InputError, match=r"^scenario\.drives = .*one per moving joint, base first: j1, j2"
    ):
        case_from_urdf_dict(doc, tmp_path)
    with pytest.raises(dttmm.InputError, match=r"^model\.urdf = 'missing\.urdf': no such file"):
        case_from_urdf_dict(_doc(urdf="missing.urdf"), tmp_path)


def test_tool_sag_against_the_exudyn_peer():
    """The arm of the sag test (the UR5's upper arm a tube, the rest rigid, joints held at zero)
    by Exudyn's 3-D geometrically exact beam with its rigid bodies
    (``reference_models.exudyn_beam3d``): the tool point converges to the DT-TMM's at second
    order (measured 1.2e-6, 3.0e-7, 7.6e-8 m at k = 2, 4, 8; sag 0.13149, 0.13241, 0.13263 mm
    against the DT-TMM's 0.13271 mm)."""
    _robots()
    pytest.importorskip("exudyn")
    from dttmm import Constant
    from reference_models import exudyn_beam3d as xb

    overlay = {"upper_arm_link": {"section": TUBE, "material": "aluminium", "keep_inertia": True}}
    arm = read_urdf(UR5, overlay, tool="tool0")
    case = arm.case(Scenario(1.0, 0.5, tuple(Drive("motion", Constant(0.0)) for _ in range(6))))
    ref = sp.statics(case, elements_per_link=4).tip_position
    gaps = [
        np.linalg.norm(xb.statics(case, elements_per_link=k, load_steps=1)["link_tip"][-1] - ref)
        for k in (2, 4)
    ]
    assert gaps[0] < 3e-6 and 3.0 < gaps[0] / gaps[1] < 5.0, gaps


@pytest.mark.parametrize(("name", "ratio"), [("ur5", 3.0), ("panda", 2.0)])
def test_shipped_cases_against_the_exudyn_peer(name, ratio):
    """The shipped robot cases, 0.1 s of the pick-and-place move (released under gravity at
    t = 0), by Exudyn's 3-D beam with its rigid bodies at k = 2 and 4 against the DT-TMM at k = 4
    (h = 5e-4 both): the tool point's gap falls with k (measured: UR5 2.0e-5, 5.0e-6 m; Panda
    1.5e-5, 5.9e-6 m; the tubes bend by up to 0.10 and 0.05 mm)."""
    _robots()
    pytest.importorskip("exudyn")
    from reference_models import exudyn_beam3d as xb

    case = dttmm.load_case(ROBOTS / f"{name}.toml")
    short = dataclasses.replace(
        case, scenario=dataclasses.replace(case.scenario, duration=0.1, output_step=0.01)
    )
    ref = sp.simulate(short, elements_per_link=4, h=5e-4)
    gaps = [
        np.abs(xb.simulate(short, elements_per_link=k, h=5e-4).end_effector - ref.end_effector).max()
        for k in (2, 4)
    ]
    assert gaps[0] < 3e-5 and gaps[0] / gaps[1] > ratio, gaps


def test_export_and_import_agree():
    """``dttmm urdf`` of the shipped flexible Panda (its rigid limit as URDF, written by
    dttmm/urdf.py) read back by :func:`read_urdf`: the DT-TMM's q̈ of the re-imported rigid arm =
    ``pin.aba`` of the rigid limit that ``reference_models.pinocchio_spatial`` builds from the
    flexible case (the beams as rods, the kept bodies, the locked joints welded)."""
    _robots()
    pin = pytest.importorskip("pinocchio")
    from dttmm.urdf import case_to_urdf
    from reference_models import pinocchio_spatial as ps

    case = dttmm.load_case(ROBOTS / "panda.toml")
    torques = Scenario(1.0, 0.1, tuple(Drive("torque", Sine(0.0, 1.0)) for _ in range(7)))
    back = read_urdf(case_to_urdf(case), gravity=case.model.gravity).case(torques)
    model = ps.build_model(case.model)
    data = model.createData()
    rng = np.random.default_rng(6)
    for _ in range(2):
        q, v = rng.normal(size=7), rng.normal(size=7)
        tau = 5 * rng.normal(size=7)
        ref = pin.aba(model, data, q, v, tau)
        qdd = sp.accelerations(back, 1, q, v, 0.0, forces=tau, engine="python")
        assert np.max(np.abs(qdd - ref)) < 1e-11 * np.max(np.abs(ref))
