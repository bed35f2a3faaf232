"""The Riccati sweep takes the 26 link constants of a link from
``dttmm.kernel.element.link_constants`` (once per link, outside the element loop); were they
written out inline again, the tuple must be that one's, entry for entry, or the physics silently
breaks. Both are read from the sources with ``ast`` and compared."""

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


def riccati_link_constants() -> list[str]:
    """The entries of ``lc = ...`` in ``riccati.backward``: those of ``link_constants`` where it
    calls it with the link's index and gravity, else those of the tuple written out."""
    fn = _function(KERNEL / "riccati.py", "backward")
    assign = next(
        n for n in ast.walk(fn) if isinstance(n, ast.Assign) and [ast.unparse(t) for t in n.targets] == ["lc"]
    )
    if isinstance(assign.value, ast.Call):
        assert ast.unparse(assign.value) == "link_constants(md, i, g0, g1)"
        return reference_tuple()
    return _entries(assign.value)


def test_link_constants_has_26_entries_and_reads_link_i():
    ref = reference_tuple()
    assert len(ref) == 26
    assert all("[i" in e or e.startswith("m") for e in ref)


def test_riccati_reads_the_link_constants_of_link_constants():
    assert riccati_link_constants() == reference_tuple()
