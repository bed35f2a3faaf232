"""The method registry is the one place that lists methods (experiments/methods.py).

How the "no lists elsewhere" check works: every module of the harness (``experiments/`` and
``reports/``, the registry itself left out) is parsed with :mod:`ast`, and every list, tuple, set
or dict literal is searched for string constants that are method names (runnable or shown). A
literal holding two or more of them is a hand-kept list of methods and fails the test; a single
name (a default, a docstring example) is allowed.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

from experiments import methods
from experiments.plan import PLANS

ROOT = Path(__file__).resolve().parents[1]
HARNESS = ("experiments", "reports")


def _literal_names(tree, known) -> list[tuple[int, list[str]]]:
    hits = []
    for node in ast.walk(tree):
        if isinstance(node, (ast.List, ast.Tuple, ast.Set)):
            elts = node.elts
        elif isinstance(node, ast.Dict):
            elts = [*(k for k in node.keys if k is not None), *node.values]
        else:
            continue
        found = [e.value for e in elts if isinstance(e, ast.Constant) and e.value in known]
        if len(set(found)) >= 2:
            hits.append((node.lineno, sorted(set(found))))
    return hits


def test_no_module_outside_the_registry_lists_methods():
    known = set(methods.shown_order())
    assert {"dttmm", "global", "exudyn-ancf", "mujoco-chain", "pinocchio-rigid"} <= known
    offenders = []
    for pkg in HARNESS:
        for path in sorted((ROOT / pkg).rglob("*.py")):
            if path == ROOT / "experiments" / "methods.py":
                continue
            for line, names in _literal_names(ast.parse(path.read_text()), known):
                offenders.append(f"{path.relative_to(ROOT)}:{line}: {names}")
    assert not offenders, "method lists outside experiments/methods.py:\n" + "\n".join(offenders)


def test_the_scan_finds_a_planted_list():
    """The check above can fail: a literal like the old hand-kept lists is found."""
    tree = ast.parse('FLEX = ["dttmm", "global", "other"]\nONE = ("dttmm", 3)\n')
    assert _literal_names(tree, set(methods.names())) == [(1, ["dttmm", "global"])]


def test_studies_derive_their_methods_from_the_records():
    p = PLANS["quick"].studies
    assert all(params.methods is None for params in p.values())
    conv = [
        m for m in methods.takes_part("convergence_k", flexible=True) if m in methods.METHODS
    ]  # built-ins
    assert conv == ["dttmm", "dttmm-2nd", "global", "exudyn-ancf", "exudyn-beam", "amm"]
    # an explicit method sits out the k study with its reason; the rigid baseline too
    assert "step falls with k" in methods.get("mujoco-chain").why_not("convergence_k")
    assert methods.get("pinocchio-rigid").why_not("convergence_k")
    # the work-precision path gives an explicit method its own step (the stable step ∝ 1/k²)
    from experiments.studies._common import step_for

    assert step_for("mujoco-chain", 8, 1e-3) == pytest.approx(2.5e-4)
    assert step_for("dttmm", 8, 1e-3) == 1e-3


def test_like_for_like_pairs_follow_the_strain():
    pairs = dict(methods.ratio_pairs())
    assert pairs["global"][-1] == "dttmm" and pairs["exudyn-ancf"] == ("dttmm-2nd",)
    # a peer of the linear strain is measured against the linear DT-TMM, never dropped
    assert pairs["mujoco-chain"][-1] == "dttmm"
    assert "pinocchio-rigid" not in pairs  # the baseline has no partner of its strain


def test_cache_key_holds_the_method_libraries():
    from experiments import fingerprint

    assert "mujoco" in fingerprint.code_version("mujoco-chain")["libraries"]
    assert "exudyn" in fingerprint.code_version("exudyn-ancf")["libraries"]
    assert "mujoco" not in fingerprint.code_version("dttmm")["libraries"]


def test_every_peer_setting_names_its_source():
    from reports.peers import peer_settings

    rows = peer_settings()
    assert rows and all(r[4] for r in rows)
    assert any("Exudyn ANCF" in r[0] and "Exudyn GE beam" in r[0] for r in rows)  # shared, listed once


def test_bad_records_are_refused():
    from dttmm.errors import InputError

    with pytest.raises(InputError, match="role"):
        methods.Method("x", None, role="oracle")
    with pytest.raises(InputError, match="capabilities"):
        methods.Method("x", None, capabilities={"teleport"})
    with pytest.raises(InputError, match="discretisation"):
        methods.Method("x", None, discretisation="voxels per link")
