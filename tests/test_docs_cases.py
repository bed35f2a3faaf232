"""docs/cases.md cannot drift from the schema: every key, every default, every example."""

from __future__ import annotations

import math
import re
import tomllib
from pathlib import Path

import pytest

import dttmm
from dttmm import case, drives, model
from dttmm.schema import fields_model

ROOT = Path(__file__).resolve().parents[1]
DOC = (ROOT / "docs" / "cases.md").read_text()

# the models documented, each by a "<!-- schema: Name -->" marker before its table
DOCUMENTED = {
    "CaseFile": case.CaseFile,
    "ModelFile": case.ModelFile,
    "LinkFile": case.LinkFile,
    "BodyFields": fields_model(model.Hub),
    "PayloadFields": fields_model(model.Payload),
    "RigidBodyFields": fields_model(model.RigidBody, ("mass", "com", "inertia")),
    "ScenarioFile": case.ScenarioFile,
    "DriveFields": fields_model(drives.Drive),
    **{f"{drives.LAWS[n].__name__}Fields": m for n, m in drives.LAW_FIELDS.items()},
}


def _tables() -> dict[str, list[list[str]]]:
    out = {}
    for m in re.finditer(r"<!-- schema: (\w+) -->\n((?:\|.*\n)+)", DOC):
        rows = [[c.strip() for c in line.strip().strip("|").split("|")] for line in m[2].splitlines()]
        out[m[1]] = rows[2:]  # skip header and separator
    return out


TABLES = _tables()


def test_every_schema_model_has_a_table():
    assert set(TABLES) == set(DOCUMENTED)


@pytest.mark.parametrize("name", sorted(DOCUMENTED))
def test_table_keys_are_the_schema_fields(name):
    keys = {row[0].strip("`") for row in TABLES[name]}
    fields = set(DOCUMENTED[name].model_fields) | ({"law"} if name == "DriveFields" else set())
    assert keys == fields


@pytest.mark.parametrize("name", sorted(DOCUMENTED))
def test_table_defaults_are_the_schema_defaults(name):
    model = DOCUMENTED[name]
    for row in TABLES[name]:
        key, default = row[0].strip("`"), row[3]
        if key not in model.model_fields:  # "law", the tag of the drive tables
            assert default == "required"
            continue
        f = model.model_fields[key]
        if default == "required":
            assert f.is_required(), key
        elif default == "none":
            assert not f.is_required() and f.default is None, key
        else:
            want = tomllib.loads(f"x = {default.strip('`')}")["x"]
            got = list(f.default) if isinstance(f.default, tuple) else f.default  # a TOML list
            assert got == want or (isinstance(got, float) and math.isinf(got) and want == got), key


def _examples() -> list[str]:
    return re.findall(r"```toml\n(.*?)```", DOC, flags=re.DOTALL)


def test_there_is_one_example_per_drive_law():
    laws = [tomllib.loads(e)["scenario"]["drives"][0]["law"] for e in _examples()]
    assert sorted(laws) == sorted(drives.LAW_FIELDS)


@pytest.mark.parametrize("i", range(5))
def test_each_example_loads(tmp_path, i):
    p = tmp_path / "example.toml"
    p.write_text(_examples()[i])
    case = dttmm.load_case(p)
    assert case.n_joints == 1


def test_shipped_examples_match_the_shipped_files(tmp_path):
    # the doc says two examples are the shipped cases: they must load equal to them
    for text in _examples():
        name = tomllib.loads(text).get("name")
        shipped = ROOT / "experiments" / "cases" / f"{name}.toml"
        if name in ("single_link", "spin_up"):
            p = tmp_path / f"{name}.toml"
            p.write_text(text)
            assert dttmm.load_case(p) == dttmm.load_case(shipped)


OWNED = [
    "docs/cases.md",
    "dttmm/case.py",
    "dttmm/schema.py",
    "dttmm/resources.py",
    "dttmm/cli.py",
    "dttmm/simulate_cli.py",
    "dttmm/drives.py",
    "dttmm/model.py",
    "dttmm/scenario.py",
    "dttmm/_validate.py",
    "dttmm/urdf.py",
]


@pytest.mark.parametrize("rel", OWNED)
def test_every_file_path_mentioned_exists(rel):
    text = (ROOT / rel).read_text()
    paths = set(re.findall(r"\b((?:[\w.-]+/)+[\w.-]+\.(?:toml|py|md))\b", text))
    missing = sorted(p for p in paths if not (ROOT / p).exists())
    assert not missing
