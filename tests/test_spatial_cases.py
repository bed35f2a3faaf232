"""Spatial case files (experiments/cases/spatial/, format in docs/cases.md "Spatial cases"):
loaded strictly, every bad key or value refused naming the field; the planar format unchanged
(``dttmm.spatial.load_case`` reads a planar file as its embedding: tests/test_spatial_from_planar.py)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import dttmm
from dttmm.errors import InputError
from dttmm.spatial import SpatialCase, case_from_dict, load_case, simulate

ROOT = Path(__file__).resolve().parent.parent / "experiments" / "cases"
FILES = sorted((ROOT / "spatial").glob("*.toml"))


def minimal(**link):
    d = {"length": 1.0, "GJ": 1.0, "EIy": 1.0, "EIz": 1.0, "rhoA": 1.0, "rhoJ": 1e-3, **link}
    return {"model": {"links": [d]}, "scenario": {"duration": 1.0, "output_step": 0.1}}


def test_shipped_spatial_cases_load_and_run():
    names = {p.stem for p in FILES}
    assert {"cantilever_3d", "two_joint_arm", "three_joint_arm"} <= names
    for p in FILES:
        case = load_case(p)
        assert isinstance(case, SpatialCase) and case.name == p.stem
        sc = case.scenario
        short = SpatialCase(case.model, dttmm.Scenario(0.02, 0.01, sc.drives))
        r = simulate(short, elements_per_link=2, h=1e-3)
        assert r.status == "ok" and np.isfinite(r.end_effector).all()
        assert r.end_effector.shape == (3, 3)


def test_three_joint_arm_is_yaw_pitch_pitch_with_gravity_and_payload():
    case = load_case(ROOT / "spatial" / "three_joint_arm.toml")
    axes = [link.joint.axis for link in case.model.links]
    assert axes == [(0.0, 0.0, 1.0), (0.0, 1.0, 0.0), (0.0, 1.0, 0.0)]
    assert case.model.gravity == (0.0, 0.0, -9.81)
    assert case.model.links[-1].payload.mass > 0
    assert case.model.base_xyz == (0.0, 0.0, 0.3)
    assert case.model.links[1].beam.roll == 0.2


@pytest.mark.parametrize(
    ("doc", "field", "hint"),
    [
        (minimal(rhoj=1.0), "model.links[0].rhoj", "did you mean 'rhoJ'"),
        (minimal(joint={"axes": [0, 0, 1]}), "model.links[0].joint.axes", "did you mean 'axis'"),
        (minimal(joint={"axis": [0, 2, 0]}), "model.links[0].joint.axis", "unit vector"),
        (minimal(joint={"axis": [0, 0]}), "model.links[0].joint.axis", "at least 3"),
        (
            minimal(hub={"mass": 1.0, "inertia": [1.0, -1.0, 1.0]}),
            "model.links[0].hub.inertia",
            "semi-definite",
        ),
        (
            minimal(payload={"mass": 1.0, "inertia": [[1, 2, 0], [0, 1, 0], [0, 0, 1]]}),
            "model.links[0].payload.inertia",
            "symmetric",
        ),
        (minimal(EIy=-1.0), "model.links[0].EIy", "positive"),
        (minimal(GJ=True), "model.links[0].GJ", "number"),
        (minimal(joint={"locked": 1}), "model.links[0].joint.locked", "true or false"),
    ],
)
def test_bad_values_are_refused_naming_the_field(doc, field, hint):
    with pytest.raises(InputError) as exc:
        case_from_dict(doc)
    assert exc.value.field == field and hint in str(exc.value)


def test_unknown_keys_are_refused_with_the_nearest_key():
    doc = minimal()
    doc["model"]["bse"] = {"rpy": [0, 0, 0]}
    with pytest.raises(InputError, match="did you mean 'base'"):
        case_from_dict(doc)
    doc = minimal()
    doc["model"]["gravity"] = [0.0, -9.81]
    with pytest.raises(InputError, match=r"model\.gravity"):
        case_from_dict(doc)
    doc = minimal()
    doc["scenario"]["drives"] = []
    with pytest.raises(InputError, match="one drive per unlocked joint"):
        case_from_dict(doc)


def test_planar_files_stay_planar():
    for p in sorted(ROOT.glob("*.toml")):  # dttmm.spatial.load_case reads them embedded
        assert isinstance(dttmm.load_case(p), dttmm.Case)
        assert load_case(p) == SpatialCase.from_planar(dttmm.load_case(p))
    from dttmm import case as planar

    for p in FILES:  # dttmm.load_case reads a file marked kind = "spatial" as a spatial case
        assert dttmm.load_case(p) == load_case(p)
        doc = dttmm.case_to_dict(load_case(p))
        assert doc["kind"] == "spatial" and case_from_dict(doc) == load_case(p)  # reads back equal
        with pytest.raises(InputError, match="unknown key"):  # the planar layer refuses it
            planar.load_case(p)
        del doc["kind"]
        with pytest.raises(InputError, match="unknown key"):
            planar.case_from_dict(doc)


def test_docs_tables_are_the_schema_fields():
    import re

    from dttmm.spatial import case as sc

    doc = (ROOT.parent.parent / "docs" / "cases.md").read_text()
    tables = {}
    for m in re.finditer(r"<!-- spatial-schema: (\w+) -->\n((?:\|.*\n)+)", doc):
        rows = [[c.strip() for c in line.strip().strip("|").split("|")] for line in m[2].splitlines()][2:]
        tables[m[1]] = {r[0].strip("`") for r in rows}
    models = {
        n: getattr(sc, n)
        for n in ("SpatialCaseFile", "SpatialModelFile", "SpatialLinkFile", "JointFile", "LoadFile")
    }
    assert set(tables) == set(models)
    for name, keys in tables.items():
        assert keys == set(models[name].model_fields), name
    example = re.search(r"Example \(a yaw joint.*?```text\n(.*?)```", doc, flags=re.DOTALL)[1]
    import tomllib

    case = case_from_dict(tomllib.loads(example))
    assert case.n_joints == 1
    load = re.search(r"then 0:\n\n```text\n(.*?)```", doc, flags=re.DOTALL)[1]
    doc_case = tomllib.loads(example + "\n" + load)
    doc_case["model"]["links"][0]["joint"] = {"locked": True}
    doc_case["scenario"]["drives"] = []
    (ld,) = case_from_dict(doc_case).scenario.loads
    assert ld == load_case(ROOT / "spatial" / "right_angle_cantilever.toml").scenario.loads[0]
