"""Compile the numba kernels once, before the test workers start (``tests/conftest.py``).

A fresh checkout has no numba cache (it lives in ``__pycache__`` beside the sources): without
this, every pytest-xdist worker (and every CLI or example subprocess started meanwhile) compiles
the planar and the spatial kernel itself on its first call, side by side, for the same
signatures — minutes of duplicated compilation. Here the kernels are compiled by tiny runs of
the same public calls the tests make (so the same signatures), in a few processes side by side,
one group of kernels each; the workers then load them from the disk cache.

``python tests/_warmup.py FAMILY ...`` compiles the named families in this process;
:func:`cold_families` says which families have no cache yet. The runs' results are not checked
here: they only compile (the tests check the physics).
"""

from __future__ import annotations

import dataclasses as dc
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
CASES = ROOT / "experiments" / "cases"


def _short(case, duration: float, output_step: float):
    return dc.replace(case, scenario=dc.replace(case.scenario, duration=duration, output_step=output_step))


def planar() -> None:
    """The planar kernel: loop.accel, recorder.record, loop.run (one signature each)."""
    import dttmm

    case = _short(dttmm.load_case(CASES / "three_link.toml"), 4e-3, 1e-3)
    dttmm.simulate(case, elements_per_link=2, h=1e-3)


def global_solver() -> None:
    """The global solver (reference_models.global_newmark): forward_closed, run, kinetic."""
    import dttmm
    from reference_models import global_newmark

    case = _short(dttmm.load_case(CASES / "three_link.toml"), 4e-3, 1e-3)
    global_newmark.simulate(case, elements_per_link=2, h=1e-3)


def assumed_modes() -> None:
    """The assumed modes method: assemble (modes), run and outputs (simulate)."""
    import dttmm
    from reference_models import assumed_modes as am

    case = dttmm.load_case(CASES / "single_link.toml")
    am.modes(case, 2)
    am.simulate(_short(dttmm.load_case(CASES / "spin_up.toml"), 8e-3, 2e-3), elements_per_link=2, h=2e-3)


def spatial() -> None:
    """The spatial kernel: loop.start, loop.run, core.energy (a run), core.accelerations."""
    import numpy as np

    import dttmm
    import dttmm.spatial

    case = dttmm.load_case(CASES / "spatial" / "two_joint_arm.toml")
    n = dttmm.spatial.simulate(_short(case, 4e-3, 1e-3), elements_per_link=2, h=1e-3).meta["n_dof"]
    dttmm.accelerations(case, 2, np.zeros(n), np.zeros(n))


def spatial_global() -> None:
    """The spatial global solver's compiled mechanics: assemble, chain (the frames of the loads
    and closures) and strain_forces (the second-order strain)."""
    import dttmm
    from reference_models import spatial_global

    case = _short(dttmm.load_case(CASES / "spatial" / "topology" / "four_bar.toml"), 2e-3, 1e-3)
    spatial_global.simulate(case, elements_per_link=1, h=1e-3, strain="second-order")


#: family → (its run, the cache folder and the index files of its entry points)
def _planar_cache():
    from dttmm.kernel import _jit

    return _jit.CACHE_DIR, ("loop.run-", "loop.accel-", "recorder.record-")


def _spatial_cache():
    from dttmm.spatial.kernel import _jit

    return _jit.CACHE_DIR, ("loop.start-", "loop.run-", "core.energy-", "core.accelerations-")


def _global_cache():
    from reference_models import _global_numba

    return _global_numba._CACHE_DIR, ("_global_numba.run-", "_global_numba.forward_closed-")


def _spatial_global_cache():
    from reference_models import _spatial_numba

    return _spatial_numba._CACHE_DIR, tuple(
        f"_spatial_numba.{f}-" for f in ("assemble", "chain", "strain_forces")
    )


def _amm_cache():
    import numba  # noqa: F401  (without numba the assumed modes run uncompiled: nothing to warm)

    return str(ROOT / "reference_models" / "__pycache__"), ("_amm_numba.run-", "_amm_numba.assemble-")


FAMILIES = {
    "spatial": (spatial, _spatial_cache),
    "planar": (planar, _planar_cache),
    "global": (global_solver, _global_cache),
    "amm": (assumed_modes, _amm_cache),
    "spatial_global": (spatial_global, _spatial_global_cache),
}

#: the processes of a warm-up, side by side: their compile times are about equal (measured on a
#: fresh checkout: the spatial kernel about as long as the planar kernel, the global solver and
#: the assumed modes together; the spatial global solver's mechanics about 20 s)
GROUPS = (("spatial", "spatial_global"), ("planar", "global", "amm"))


def cold_families() -> list[str]:
    """The families whose entry points have no index file in their numba cache folder (a fresh
    checkout, or an edited kernel: its cache folder is named by a hash of its sources)."""
    cold = []
    for name, (_, cache) in FAMILIES.items():
        try:
            folder, entries = cache()
        except ImportError:  # numba (or an optional engine) missing: nothing to compile
            continue
        if folder is None:
            continue
        names = {p.name for p in Path(folder).rglob("*.nbi")}
        if not all(any(n.startswith(e) for n in names) for e in entries):
            cold.append(name)
    return cold


def main(names: list[str]) -> int:
    for name in names:
        t0 = time.perf_counter()
        FAMILIES[name][0]()
        print(f"warm-up {name}: {time.perf_counter() - t0:.1f} s", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
