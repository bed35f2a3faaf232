"""Shared fixtures: the case files and small helpers to shorten or modify cases."""

from __future__ import annotations

import dataclasses as dc
import functools
import os
import re
import socket
import subprocess
import sys
import time
from pathlib import Path

import pytest

import dttmm

CASES = Path(__file__).resolve().parents[1] / "experiments" / "cases"
TESTS = Path(__file__).resolve().parent
ROOT = TESTS.parent


def case(name: str) -> dttmm.Case:
    return dttmm.load_case(CASES / f"{name}.toml")


def shortened(c: dttmm.Case, duration: float, output_step: float | None = None) -> dttmm.Case:
    s = c.scenario
    return dc.replace(c, scenario=dc.replace(s, duration=duration, output_step=output_step or s.output_step))


def with_links(c: dttmm.Case, **beam_changes) -> dttmm.Case:
    """Replace beam fields of every link (e.g. EI=...)."""
    links = tuple(
        dc.replace(
            l,
            beam=dc.replace(
                l.beam, **{k: (v(l.beam) if callable(v) else v) for k, v in beam_changes.items()}
            ),
        )
        for l in c.model.links
    )
    return dc.replace(c, model=dc.replace(c.model, links=links))


@pytest.fixture
def single_link():
    return case("single_link")


@pytest.fixture
def three_link():
    return case("three_link")


@pytest.fixture
def spin_up():
    return case("spin_up")


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.fixture
def loopback_cluster(tmp_path):
    """A dask scheduler and two single-thread workers started as separate processes."""
    bin_dir = Path(sys.executable).parent
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(TESTS), str(ROOT)]), "OPENBLAS_NUM_THREADS": "1"}
    addr = f"tcp://127.0.0.1:{_free_port()}"
    common = dict(env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, cwd=tmp_path)
    procs = [
        subprocess.Popen(
            [
                str(bin_dir / "dask"),
                "scheduler",
                "--host",
                "127.0.0.1",
                "--port",
                addr.rsplit(":", 1)[1],
                "--no-dashboard",
            ],
            **common,
        )
    ]
    try:
        for _ in range(2):
            procs.append(
                subprocess.Popen(
                    [
                        str(bin_dir / "dask"),
                        "worker",
                        addr,
                        "--nthreads",
                        "1",
                        "--nworkers",
                        "1",
                        "--no-dashboard",
                        "--no-nanny",
                    ],
                    **common,
                )
            )
        from dask.distributed import Client

        deadline = time.time() + 60
        while True:
            try:
                with Client(addr, timeout=5) as c:
                    c.wait_for_workers(2, timeout=60)
                break
            except OSError:
                if time.time() > deadline:
                    raise
                time.sleep(0.5)
        yield addr
    finally:
        for p in reversed(procs):
            p.terminate()
        for p in procs:
            try:
                p.wait(timeout=10)
            except subprocess.TimeoutExpired:
                p.kill()


@pytest.fixture
def cleanup():
    """Unregister, after the test, every method the test registered (experiments.methods)."""
    from experiments import methods

    before = set(methods.names())
    yield
    for n in set(methods.names()) - before:
        methods.unregister(n)


def pytest_sessionstart(session):
    """On a fresh checkout (no numba cache yet), compile the kernels once before the xdist
    workers start: a few processes side by side, one group of kernels each (tests/_warmup.py).
    Without it every worker compiles the same kernels itself, side by side. Only in the
    controlling process of an xdist run; ``DTTMM_TEST_WARMUP=0`` turns it off."""
    config = session.config
    if hasattr(config, "workerinput") or not getattr(config.option, "numprocesses", None):
        return
    if os.environ.get("DTTMM_TEST_WARMUP", "1") == "0" or config.option.collectonly:
        return
    import _warmup

    cold = _warmup.cold_families()
    groups = [[f for f in g if f in cold] for g in _warmup.GROUPS]
    groups = [g for g in groups if g]
    if not groups:
        return
    env = {
        **os.environ,
        "PYTHONPATH": os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")]),
        "OPENBLAS_NUM_THREADS": "1",
    }
    t0 = time.perf_counter()
    procs = [
        subprocess.Popen(
            [sys.executable, str(TESTS / "_warmup.py"), *g],
            env=env,
            cwd=ROOT,
            stdout=subprocess.PIPE,
            stderr=subprocess.STDOUT,
            text=True,
        )
        for g in groups
    ]
    lines = []
    for g, p in zip(groups, procs):
        out, _ = p.communicate()
        # a failed warm-up only costs time: the tests compile what is missing (and show the error)
        lines.append(f"{'+'.join(g)}: " + ("ok" if p.returncode == 0 else f"failed ({out.strip()[-300:]})"))
    tr = config.pluginmanager.get_plugin("terminalreporter")
    if tr is not None:
        tr.write_line(f"numba warm-up ({time.perf_counter() - t0:.0f} s): " + "; ".join(lines))


_MODULE_FIXTURE = re.compile(r"""@pytest\.fixture\(\s*scope\s*=\s*["']module["']""")


@functools.cache
def _has_module_fixture(module: str) -> bool:
    path = ROOT / module
    return path.suffix == ".py" and path.is_file() and bool(_MODULE_FIXTURE.search(path.read_text()))


@pytest.hookimpl(tryfirst=True, optionalhook=True)
def pytest_xdist_make_scheduler(config, log):
    """``--dist loadgroup`` (pyproject's addopts): a module with a module-scoped fixture runs on
    one xdist worker, its fixtures computed once (test_report's report, about 40 s, and the
    report drawn again, about 40 s, were computed in both workers of a 2-worker run); every
    other test is scheduled alone, as with ``--dist load``. ``xdist_group`` marks keep their
    meaning where pytest carries them in the node id (xdist 3.8 writes ``item._nodeid``, which
    pytest 9.2 no longer reads, so its own loadgroup scheduler sees no groups)."""
    if config.getvalue("dist") != "loadgroup":
        return None
    from xdist.scheduler import LoadScopeScheduling

    class ModuleFixtureScheduling(LoadScopeScheduling):
        def _split_scope(self, nodeid: str) -> str:
            if nodeid.rfind("@") > nodeid.rfind("]"):
                return nodeid.split("@")[-1]
            module = nodeid.split("::", 1)[0]
            return module if _has_module_fixture(module) else nodeid

    return ModuleFixtureScheduling(config, log)
