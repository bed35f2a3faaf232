"""Cost per step of DT-TMM against the compiled global-equation solver, in k and in n.

Both solvers run the same discretisation, integrator (Newmark, h = 1 ms) and iteration rule,
so they take the same number of iterations per step; the table gives the CPU time per step
of each, their ratio, fitted exponents (cost ~ N^p, N the number of coordinates) and the
crossover where DT-TMM becomes the cheaper one. A second table compares the compiled global
engine with the same source run uncompiled (``engine="python"``: agreement and speed-up).

Cost per step is measured by differencing: CPU time (``time.process_time``, min of
``--repeats`` runs) of a run of 3s steps minus that of s steps, divided by 2s, so model
set-up, compilation and output recording cancel. Run with one BLAS thread:

    OPENBLAS_NUM_THREADS=1 python -m experiments.global_scaling [--quick] [--out data/bench]
"""

from __future__ import annotations

import argparse
import csv
import dataclasses as dc
import math
import time
from pathlib import Path

import numpy as np

import dttmm
from experiments import methods
from experiments.fit import slope
from reference_models import global_newmark as gn

CASES = Path(__file__).resolve().parent / "cases"
H = 1e-3
KS = [1, 2, 4, 8, 16, 32, 64, 128, 256]
NS = [1, 2, 3, 4, 6, 8, 12]
K_LINKS = 8
K_ENGINES = [4, 16]  # the uncompiled engine needs ~10 s per step at k = 64


def three_link(n_steps: int) -> dttmm.Case:
    c = dttmm.load_case(CASES / "three_link.toml")
    return dc.replace(c, scenario=dc.replace(c.scenario, duration=n_steps * H, output_step=n_steps * H))


def chain(n_links: int, n_steps: int) -> dttmm.Case:
    """n links with three_link's link data: its first link at the base, its middle link
    repeated, its last link (with the payload) at the tip; sine torques at every joint."""
    base = dttmm.load_case(CASES / "three_link.toml")
    first, mid, last = base.model.links
    if n_links == 1:
        links = [dc.replace(first, payload=last.payload)]
    else:
        links = [first] + [mid] * (n_links - 2) + [last]
    drives = tuple(dttmm.Drive("torque", dttmm.Sine(1.0 / (i + 1), 1.0, until=1.0)) for i in range(n_links))
    return dttmm.Case(
        dc.replace(base.model, links=tuple(links)),
        dttmm.Scenario(n_steps * H, n_steps * H, drives),
        f"chain{n_links}",
    )


def _run(method: str, case: dttmm.Case, k: int) -> dttmm.Result:
    if method == "dttmm":
        return dttmm.simulate(case, elements_per_link=k, h=H, cut_loads=False, energy=False)
    return gn.simulate(case, elements_per_link=k, h=H, engine="numba" if method == "global" else "python")


def _cpu(method, case, k, repeats) -> tuple[float, dttmm.Result]:
    best, res = math.inf, None
    for _ in range(repeats):
        t0 = time.process_time()
        res = _run(method, case, k)
        best = min(best, time.process_time() - t0)
    return best, res


def cost_per_step(method: str, make, k: int, repeats: int, budget: float) -> dict:
    """CPU seconds per step by differencing runs of s and 3s steps (s from a probe run)."""
    _run(method, make(2), k)  # compile / warm the caches
    t_probe, _ = _cpu(method, make(4), k, 1)
    s = int(min(200, max(2, budget / max(t_probe / 4, 1e-7) / 4)))
    t1, _ = _cpu(method, make(s), k, repeats)
    t3, res = _cpu(method, make(3 * s), k, repeats)
    per = (t3 - t1) / (2 * s)
    if per <= 0:  # timer resolution: fall back to the long run
        per = t3 / (3 * s)
    return {
        "cost": per,
        "steps": s,
        "n_dof": res.meta.get("n_dof"),
        "iterations": res.meta.get("iterations_mean"),
    }


def crossover(x, a, b) -> float:
    """Smallest x where a (DT-TMM) falls below b (global), log-interpolated; x[0] if at once, NaN if never."""
    r = np.log(np.asarray(a) / np.asarray(b))
    if r[0] < 0:
        return float(x[0])
    for i in range(1, len(x)):
        if r[i] < 0:
            lx = np.log(x[i - 1]) + (np.log(x[i]) - np.log(x[i - 1])) * r[i - 1] / (r[i - 1] - r[i])
            return float(np.exp(lx))
    return math.nan


def scaling(sizes, make_for, k_for, repeats, budget, label) -> list[dict]:
    rows = []
    for size in sizes:
        row = {"study": label, "size": size}
        for method in methods.same_equations()[0]:  # DT-TMM and the global solver, linear strain
            m = cost_per_step(method, make_for(size), k_for(size), repeats, budget)
            row.update(
                {
                    f"{method}_cost": m["cost"],
                    f"{method}_steps": m["steps"],
                    f"{method}_iterations": m["iterations"],
                }
            )
            if method == "global":
                row["n_dof"] = m["n_dof"]
        row["ratio_global_over_dttmm"] = row["global_cost"] / row["dttmm_cost"]
        print(
            f"{label:6s} {size:4d}  N={row['n_dof']:5d}  DT-TMM {row['dttmm_cost'] * 1e6:10.1f} us/step"
            f"  global {row['global_cost'] * 1e6:12.1f} us/step  ratio {row['ratio_global_over_dttmm']:9.1f}"
            f"  iters {row['dttmm_iterations']:.2f}/{row['global_iterations']:.2f}",
            flush=True,
        )
        rows.append(row)
    return rows


def summarise(rows, label, x_key="size") -> dict:
    x = np.array([r[x_key] for r in rows], float)
    N = np.array([r["n_dof"] for r in rows], float)
    a = np.array([r["dttmm_cost"] for r in rows])
    b = np.array([r["global_cost"] for r in rows])
    tail = slice(max(0, len(rows) - 4), None)
    out = {
        "study": label,
        "dttmm_exponent_all": slope(N, a)[0],
        "global_exponent_all": slope(N, b)[0],
        "dttmm_exponent_top4": slope(N[tail], a[tail])[0],
        "global_exponent_top4": slope(N[tail], b[tail])[0],
        "crossover": crossover(x, a, b),
    }
    print(
        f"{label}: cost ~ N^p  DT-TMM p = {out['dttmm_exponent_all']:.2f} (largest 4: "
        f"{out['dttmm_exponent_top4']:.2f}); global p = {out['global_exponent_all']:.2f} (largest 4: "
        f"{out['global_exponent_top4']:.2f}); DT-TMM cheaper from {label} = {out['crossover']:.3g}"
    )
    return out


def engines(ks, repeats) -> list[dict]:
    """Compiled vs uncompiled global engine on three_link: agreement and speed-up."""
    rows = []
    for k in ks:
        case = three_link(20)
        a = gn.simulate(case, elements_per_link=k, h=H, engine="python")
        b = gn.simulate(case, elements_per_link=k, h=H, engine="numba")
        diff = max(
            np.abs(a.end_effector - b.end_effector).max(), np.abs(a.tip_deflection - b.tip_deflection).max()
        )
        c_py = cost_per_step("global-python", lambda n: three_link(n), k, repeats, 1.0)
        c_nb = cost_per_step("global", lambda n: three_link(n), k, repeats, 0.3)
        row = {
            "k": k,
            "n_dof": b.meta["n_dof"],
            "max_diff_m": float(diff),
            "python_cost": c_py["cost"],
            "numba_cost": c_nb["cost"],
            "speedup": c_py["cost"] / c_nb["cost"],
        }
        print(
            f"engines k={k:3d} N={row['n_dof']:4d}  |python - numba| = {diff:.2e} m  python "
            f"{row['python_cost'] * 1e3:8.3f} ms/step  numba {row['numba_cost'] * 1e3:8.3f} ms/step  "
            f"speed-up {row['speedup']:.1f}",
            flush=True,
        )
        rows.append(row)
    return rows


def _write(path: Path, rows: list[dict]):
    path.parent.mkdir(parents=True, exist_ok=True)
    keys = list(dict.fromkeys(key for r in rows for key in r))
    with open(path, "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=keys)
        w.writeheader()
        w.writerows(rows)
    print(f"wrote {path}")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="small sizes, 1 repeat (a smoke run)")
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--out", type=Path, default=Path("data/bench"))
    ap.add_argument("--skip-engines", action="store_true")
    args = ap.parse_args(argv)
    ks, ns, ke = (KS[:4], NS[:3], K_ENGINES[:1]) if args.quick else (KS, NS, K_ENGINES)
    rep = 1 if args.quick else args.repeats
    budget = 0.05 if args.quick else 0.4
    rows_k = scaling(ks, lambda k: lambda n: three_link(n), lambda k: k, rep, budget, "k")
    rows_n = scaling(ns, lambda n: lambda s, n=n: chain(n, s), lambda n: K_LINKS, rep, budget, "n")
    summary = [summarise(rows_k, "k"), summarise(rows_n, "n")]
    tag = "-quick" if args.quick else ""
    _write(args.out / f"global_scaling{tag}.csv", rows_k + rows_n)
    _write(args.out / f"global_scaling_fit{tag}.csv", summary)
    if not args.skip_engines:
        _write(args.out / f"global_engines{tag}.csv", engines(ke, rep))


if __name__ == "__main__":
    main()
