"""The Riccati sweep reads the 26 link constants of an element inline (a helper would copy the
whole ``Model`` in each call, measured 7× slower); the tuple must be the one of
``dttmm.kernel.element.link_constants``, entry for entry, or the physics silently breaks.
Both are read from the sources with ``ast`` and compared."""

from __future__ import annotations

import ast
from pathlib import Path

KERNEL = Path(__file__).resolve().parent.parent / "dttmm" / "kernel"


def _function(path: Path, name: str) -> ast.FunctionDef:
    tree = ast.parse(path.read_text(), str(path))
    return next(n for n in ast.walk(tree) if isinstance(n, ast.FunctionDef) and n.name == name)


def _entries(tup: ast.Tuple) -> list[str]:
    return [ast.unparse(e) for e in tup.elts]


def reference_tuple() -> list[str]:
    """The entries of the tuple ``link_constants`` returns."""
    fn = _function(KERNEL / "element.py", "link_constants")
    ret = next(n for n in ast.walk(fn) if isinstance(n, ast.Return))
    return _entries(ret.value)


def inline_tuple() -> list[str]:
    """The entries of ``lc = (...)`` in ``riccati.backward``."""
    fn = _function(KERNEL / "riccati.py", "backward")
    assign = next(
        n
        for n in ast.walk(fn)
        if isinstance(n, ast.Assign)
        and isinstance(n.value, ast.Tuple)
        and [ast.unparse(t) for t in n.targets] == ["lc"]
    )
    return _entries(assign.value)


def test_link_constants_has_26_entries_and_reads_link_i():
    ref = reference_tuple()
    assert len(ref) == 26
    assert all("[i" in e or e.startswith("m") for e in ref)


def test_riccati_inline_link_constants_equal_link_constants():
    assert inline_tuple() == reference_tuple()
