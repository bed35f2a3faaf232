"""Every module imports alone, the project's modules import each other without cycles, and the
core package ``dttmm`` needs neither the experiments nor the reports.

The import graph is read from the sources with ``ast``: every ``import`` counts, at module
level or inside a function (a function-level import can hide a cycle but not remove it), except
those under ``if __name__ == "__main__":`` (they run only when the file is the script, so they
are not edges of the module) and under ``if TYPE_CHECKING:``. Imports of outside packages
(numpy, exudyn, pinocchio, ...) are not edges: heavy engines may be imported lazily.
"""

from __future__ import annotations

import ast
import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
PACKAGES = ("dttmm", "reference_models", "experiments", "reports")
ENGINES = ("exudyn", "pinocchio", "pin", "mujoco")  # optional: a module needing a missing one is skipped

# Cycles and layer breaks being removed in other parts of the code; delete an entry (and, once
# empty, this list) when its edge is gone. Each is (importer, imported).


def _module_name(path: Path) -> str:
    parts = list(path.relative_to(ROOT).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def project_modules() -> dict[str, Path]:
    """Module name -> file of every module of the project's packages."""
    out = {}
    for pkg in PACKAGES:
        for p in sorted((ROOT / pkg).rglob("*.py")):
            if "__pycache__" not in p.parts:
                out[_module_name(p)] = p
    return out


def _script_or_typing_block(node) -> bool:
    """``if __name__ == "__main__":`` or ``if TYPE_CHECKING:``."""
    if not isinstance(node, ast.If):
        return False
    t = node.test
    if isinstance(t, ast.Name) and t.id == "TYPE_CHECKING":
        return True
    if isinstance(t, ast.Attribute) and t.attr == "TYPE_CHECKING":
        return True
    return (
        isinstance(t, ast.Compare)
        and isinstance(t.left, ast.Name)
        and t.left.id == "__name__"
        and any(isinstance(c, ast.Constant) and c.value == "__main__" for c in t.comparators)
    )


def _imports(tree):
    """Every Import/ImportFrom node outside script and TYPE_CHECKING blocks."""
    stack = [tree]
    while stack:
        node = stack.pop()
        if isinstance(node, (ast.Import, ast.ImportFrom)):
            yield node
        for child in ast.iter_child_nodes(node):
            if not _script_or_typing_block(child):
                stack.append(child)


def _target(name: str, modules) -> str | None:
    """The project module a dotted import name loads (longest project prefix), or None."""
    parts = name.split(".")
    for i in range(len(parts), 0, -1):
        if ".".join(parts[:i]) in modules:
            return ".".join(parts[:i])
    return None


def import_graph() -> dict[str, set[str]]:
    """Module -> the project modules it imports (see the module docstring for the rules)."""
    modules = project_modules()
    graph = {}
    for name, path in modules.items():
        package = name if path.name == "__init__.py" else name.rpartition(".")[0]
        edges = set()
        for node in _imports(ast.parse(path.read_text(), str(path))):
            if isinstance(node, ast.Import):
                targets = [_target(a.name, modules) for a in node.names]
            else:
                base = node.module or ""
                if node.level:
                    up = package.split(".")[: len(package.split(".")) - (node.level - 1)]
                    base = ".".join(up + ([node.module] if node.module else []))
                targets = [_target(f"{base}.{a.name}", modules) or _target(base, modules) for a in node.names]
            edges |= {t for t in targets if t and t != name}
        graph[name] = edges
    return graph


def find_cycle(graph: dict[str, set[str]]) -> list[str] | None:
    """One cycle of ``graph`` as a list of modules (first = last), or None."""
    state, stack = {}, []

    def visit(n):
        state[n] = "open"
        stack.append(n)
        for m in sorted(graph.get(n, ())):
            if state.get(m) == "open":
                return stack[stack.index(m) :] + [m]
            if m not in state and (c := visit(m)):
                return c
        state[n] = "done"
        stack.pop()
        return None

    for n in sorted(graph):
        if n not in state and (c := visit(n)):
            return c
    return None


def test_the_graph_reader_sees_function_level_imports_and_finds_cycles():
    graph = import_graph()
    assert "experiments.methods" in graph["reports.interpret"]  # imported inside a function
    assert find_cycle({"a": {"b"}, "b": {"c"}, "c": {"a"}}) == ["a", "b", "c", "a"]
    assert find_cycle({"a": {"b"}, "b": set(), "c": {"a", "b"}}) is None


def test_no_import_cycle_among_the_projects_modules():
    graph = import_graph()
    cycle = find_cycle(graph)
    assert cycle is None, "import cycle: " + " -> ".join(cycle)


def test_dttmm_imports_neither_experiments_nor_reports():
    graph = import_graph()
    bad = sorted(
        (a, b)
        for a, bs in graph.items()
        if a.split(".")[0] == "dttmm"
        for b in bs
        if b.split(".")[0] in ("experiments", "reports")
    )
    assert bad == []
    code = "import sys, dttmm; print(sorted({m.split('.')[0] for m in sys.modules} & {'experiments', 'reports'}))"
    out = subprocess.run(
        [sys.executable, "-c", code], check=False, capture_output=True, text=True, cwd=ROOT, env=_env()
    )
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "[]"


# The DT-TMM entry point that runs the kernel; every other module of dttmm is the model layer,
# which the kernel builds on and which never reaches back into it.
KERNEL_ENTRY = {"dttmm.solver", "dttmm.spatial.solver"}  # the spatial one shares the user-law tables


def _in_kernel(module: str) -> bool:
    return module.split(".")[:2] in (["dttmm", "kernel"], ["dttmm", "kernel_python"])


def test_the_model_layer_never_imports_the_kernel():
    graph = import_graph()
    bad = sorted(
        (a, b)
        for a, bs in graph.items()
        if a.split(".")[0] == "dttmm" and not _in_kernel(a) and a not in KERNEL_ENTRY
        for b in bs
        if _in_kernel(b)
    )
    assert bad == [], f"model-layer modules importing the kernel: {bad}"
    assert any(_in_kernel(b) for b in graph["dttmm.solver"])  # the entry point does


def _env():
    return {**os.environ, "PYTHONPATH": str(ROOT), "OPENBLAS_NUM_THREADS": "1", "MPLBACKEND": "Agg"}


# Importing ``a.b.c`` into a fresh interpreter runs ``import a``, then ``import a.b`` unless ``a``
# loaded it, then ``import a.b.c`` unless loaded by then. So the probe walks the package tree in
# forked processes: a child imports one package or module into its parent's state (the state a
# fresh interpreter reaches after importing the parent alone) and forks again for each module
# below it not loaded yet. Every module thus starts from exactly the state of a fresh import, and
# each module body runs once per branch instead of once per module. The root preloads the heavy
# outside libraries (their import time would dominate) and no project module; a preload hides only
# a module-level use of an outside submodule that its module never imports (``scipy.sparse.x``
# after a bare ``import scipy``).
_PROBE = """
import importlib, json, os, sys
for lib in ("numpy", "scipy.interpolate", "scipy.optimize", "scipy.sparse", "numba", "pandas", "pydantic",
            "pyarrow", "matplotlib.pyplot", "tqdm", "dask.distributed",
            "exudyn", "pinocchio", "mujoco"):
    try:
        importlib.import_module(lib)
    except ImportError:
        pass
PROJECT = {packages!r}
assert not any(m.split(".")[0] in PROJECT for m in sys.modules), "project module preloaded"


def error(exc):
    if isinstance(exc, ModuleNotFoundError):
        return "MISSING " + str(exc.name) + ": " + str(exc)
    return type(exc).__name__ + ": " + str(exc)


def walk(prefix, names):
    # name -> None or error, for the modules `names` below `prefix` (loaded already by this process)
    out = {{n: None for n in names if n in sys.modules}}
    depth = 0 if prefix is None else prefix.count(".") + 1
    branches = {{}}
    for n in names:
        if n not in out:
            branches.setdefault(".".join(n.split(".")[: depth + 1]), []).append(n)
    for head, members in branches.items():
        r, w = os.pipe()
        pid = os.fork()
        if pid == 0:
            os.close(r)
            try:
                try:
                    importlib.import_module(head)
                    res = walk(head, [m for m in members if m != head])
                    res[head] = None
                except BaseException as exc:  # the head fails: so does every module below it alone
                    res = dict.fromkeys(members, error(exc))
                with os.fdopen(w, "w") as f:
                    f.write(json.dumps(res))
            finally:
                os._exit(0)
        os.close(w)
        with os.fdopen(r) as f:
            text = f.read()
        _, status = os.waitpid(pid, 0)
        got = json.loads(text) if text else {{}}
        for m in members:
            out[m] = got.get(m, "child died (status %d)" % status)
    return out


print(json.dumps({{n: v for n, v in walk(None, sys.argv[1:]).items() if n in sys.argv[1:]}}))
"""


def _why(msg: str | None) -> str | None:
    """None when imported; 'skip: ...' for a missing engine; else the error."""
    if msg and msg.startswith("MISSING "):
        missing = msg.split()[1].rstrip(":")
        return f"skip: engine {missing} not installed" if missing.split(".")[0] in ENGINES else msg
    return msg


def _probe(names, packages, cwd, env) -> dict[str, str | None]:
    """Module -> None (imported alone) or its error, from one run of :data:`_PROBE`."""
    import json

    out = subprocess.run(
        [sys.executable, "-c", _PROBE.format(packages=set(packages)), *names],
        check=False,
        capture_output=True,
        text=True,
        cwd=cwd,
        env=env,
        timeout=600,
    )
    assert out.returncode == 0, out.stderr[-3000:]
    return json.loads(out.stdout.strip().splitlines()[-1])


@pytest.mark.skipif(not hasattr(os, "fork"), reason="needs os.fork")
def test_the_probe_sees_a_module_that_needs_another_imported_first(tmp_path):
    pkg = tmp_path / "orderpkg"
    pkg.mkdir()
    (pkg / "__init__.py").write_text("")
    (pkg / "a.py").write_text("import json\nVALUE = 1\n")
    (pkg / "b.py").write_text("import sys\nVALUE = sys.modules['orderpkg.a'].VALUE + 1\n")  # needs a first
    (pkg / "c.py").write_text("from orderpkg.a import VALUE\n")
    (pkg / "d.py").write_text("import no_such_outside_module_xyz\n")
    env = {**os.environ, "PYTHONPATH": str(tmp_path)}
    got = _probe(["orderpkg.a", "orderpkg.b", "orderpkg.c", "orderpkg.d"], ["orderpkg"], tmp_path, env)
    assert got["orderpkg.a"] is None and got["orderpkg.c"] is None
    assert got["orderpkg.b"].startswith("KeyError") and "orderpkg.a" in got["orderpkg.b"]
    assert got["orderpkg.d"].startswith("MISSING no_such_outside_module_xyz")


@pytest.mark.skipif(not hasattr(os, "fork"), reason="needs os.fork")
def test_every_module_imports_alone():
    names = [n for n in project_modules() if not n.endswith("__main__")]
    results = {n: _why(m) for n, m in _probe(names, PACKAGES, ROOT, _env()).items()}
    assert set(results) == set(names)
    failed = {n: why for n, why in results.items() if why and not why.startswith("skip")}
    assert failed == {}
    skipped = [n for n, why in results.items() if why]
    if skipped:
        pytest.skip(f"imported all but {skipped} (engine missing)")
