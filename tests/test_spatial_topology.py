"""Trees and closed loops of spatial arms (docs/spatial.md "Trees and closed loops"): the
topology data (link names and parents, closures, the end-effector) in the model and the case
file, the engines that refuse them, the tree sweep of the spatial DT-TMM and its loop closure."""

from __future__ import annotations

import dataclasses
import tomllib
from pathlib import Path

import numpy as np
import pytest

from dttmm import InputError
from dttmm.spatial import SpatialClosure, SpatialLink, SpatialManipulator, SpatialSection
from dttmm.spatial.case import case_from_dict, case_to_dict, load_case

TOPO = Path(__file__).resolve().parents[1] / "experiments" / "cases" / "spatial" / "topology"
FOUR_BAR = TOPO / "four_bar.toml"


def _beam(length=0.3):
    return SpatialSection(length=length, GJ=30.0, EIy=40.0, EIz=40.0, rhoA=0.8, rhoJ=4e-4, EA=2e6)


def _four_bar_dict() -> dict:
    return tomllib.loads(FOUR_BAR.read_text())


def _refused(data: dict) -> InputError:
    with pytest.raises(InputError) as info:
        case_from_dict(data)
    assert "\n" not in str(info.value)
    return info.value


# ------------------------------------------------------------------ the data layer ------------


def test_four_bar_topology():
    """The shipped four-bar: two branches from the base (AB → BC, CD), one revolute cut joint."""
    case = load_case(FOUR_BAR)
    m = case.model
    assert m.link_names == ("AB", "BC", "CD")
    assert m.parents == (-1, 0, -1)
    assert m.children(-1) == (0, 2) and m.children(0) == (1,) and m.children(1) == ()
    assert m.leaves == (1, 2)
    assert m.end_effector_index == 2 and not m.serial
    assert m.n_closure_equations == 5 and m.closure_names == ("C",)
    assert case.provenance["source"].startswith("O. A. Bauchau")


def test_default_names_and_parents():
    """Unnamed links are link1, link2, …; every parent defaults to the previous link; a chain
    written with explicit parents is the same arm as one without (serial)."""
    links = (SpatialLink(_beam()), SpatialLink(_beam()), SpatialLink(_beam()))
    m = SpatialManipulator(links)
    assert m.link_names == ("link1", "link2", "link3") and m.parents == (-1, 0, 1) and m.serial
    explicit = tuple(
        dataclasses.replace(lk, name=f"l{i}", parent="base" if i == 0 else f"l{i - 1}")
        for i, lk in enumerate(links)
    )
    m2 = SpatialManipulator(explicit, end_effector="l1")
    assert m2.parents == (-1, 0, 1) and m2.serial and m2.end_effector_index == 1
    tree = SpatialManipulator((links[0], links[1], dataclasses.replace(links[2], parent="link1")))
    assert tree.parents == (-1, 0, 0) and tree.leaves == (1, 2) and not tree.serial


def test_round_trip():
    """case_to_dict → case_from_dict rebuilds the four-bar and a tree with an end-effector; the
    existing (serial) cases write no topology keys."""
    case = load_case(FOUR_BAR)
    assert case_from_dict(case_to_dict(case)) == case
    data = _four_bar_dict()
    data["model"]["end_effector"] = "BC"
    data["model"]["closures"][0]["to_point"] = [0.0, 0.0, 0.0]
    data["model"]["closures"][0]["kind"] = "spherical"
    c2 = case_from_dict(data)
    assert c2.model.end_effector == "BC" and c2.model.closures[0].to_point == (0.0, 0.0, 0.0)
    assert case_from_dict(case_to_dict(c2)) == c2
    serial = load_case(TOPO.parent / "two_joint_arm.toml")
    d = case_to_dict(serial)
    assert "closures" not in d["model"] and "end_effector" not in d["model"]
    assert all("name" not in lk and "parent" not in lk for lk in d["model"]["links"])


@pytest.mark.parametrize(
    ("edit", "field", "words"),
    [
        (lambda d: d["model"]["links"][1].update(parnet="AB"), "parnet", "parent"),
        (lambda d: d["model"]["closures"][0].update(too="CD"), "too", "to"),
        (lambda d: d["model"].update(end_efector="BC"), "end_efector", "end_effector"),
        (lambda d: d["model"]["links"][1].update(parent="CD"), "model.links[1].parent", "listed before"),
        (lambda d: d["model"]["links"][1].update(parent="XY"), "model.links[1].parent", "names no link"),
        (lambda d: d["model"]["links"][2].update(name="AB"), "model.links[2].name", "unique"),
        (lambda d: d["model"]["links"][2].update(name="ground"), "model.links[2].name", "reserved"),
        (lambda d: d["model"]["closures"][0].update(link="XY"), "model.closures[0].link", "names no link"),
        (lambda d: d["model"]["closures"][0].update(to="XY"), "model.closures[0].to", "names no link"),
        (lambda d: d["model"]["closures"][0].update(to="BC"), "model.closures[0].to", "must differ"),
        (lambda d: d["model"]["closures"][0].update(axis=[1.0, 1.0, 0.0]), "model.closures[0].axis", "unit"),
        (lambda d: d["model"]["closures"][0].update(kind="prismatic"), "model.closures[0].kind", "revolute"),
        (lambda d: d["model"].update(end_effector="XY"), "model.end_effector", "must name a link"),
        (
            lambda d: d["model"]["closures"][0].update(to_point=[0.0, 1e-3, 0.0]),
            "model.closures[0].to_point",
            "open by 0.001 m",
        ),
    ],
)
def test_refusals(edit, field, words):
    """Each bad topology entry is a one-line InputError naming the field (an unknown key with
    the nearest valid one) and its reason."""
    data = _four_bar_dict()
    edit(data)
    msg = str(_refused(data))
    assert field in msg and words in msg, msg


def test_closure_record_refusals():
    """SpatialClosure checks its own fields; the manipulator checks the names it uses."""
    with pytest.raises(InputError, match="closure.point"):
        SpatialClosure("weld", "a", point=(0.0, 1.0))
    with pytest.raises(InputError, match="closure.link"):
        SpatialClosure("weld", "ground")
    with pytest.raises(InputError, match=r"model.closures\[0\]"):
        SpatialManipulator((SpatialLink(_beam()),), closures=("C",))


def test_serial_only_engines_refuse():
    """The engines that run chains only refuse a tree or a loop in one line, naming themselves."""
    case = load_case(FOUR_BAR)
    from dttmm.spatial.inverse_dynamics import rigid_inverse_dynamics
    from dttmm.urdf import case_to_urdf

    with pytest.raises(InputError, match="trees and closed loops are not supported by the rigid inverse"):
        rigid_inverse_dynamics(case.model, np.zeros(3), np.zeros(3), np.zeros(3))
    with pytest.raises(InputError, match="trees and closed loops are not supported by the URDF export"):
        case_to_urdf(case)
    pin = pytest.importorskip("pinocchio")  # noqa: F841
    from reference_models import pinocchio_spatial

    with pytest.raises(InputError, match="not supported by pinocchio-spatial"):
        pinocchio_spatial.build_model(case.model)
