"""``dttmm simulate CASE --elements K --h H --out DIR``: run DT-TMM, write the table and a plot."""
from __future__ import annotations

import json
import sys
from pathlib import Path

from .case import load_case
from .errors import InputError, SimulationError
from .solver import simulate


def plot_result(res, path: Path, title: str = "") -> Path:
    """PNG with tip deflections (top) and joint angles (bottom) against time."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (a1, a2) = plt.subplots(2, 1, figsize=(7, 5.5), sharex=True)
    for i in range(res.n_joints):
        a1.plot(res.t, res.tip_deflection[:, i] * 1e3, label=f"link {i + 1}")
        a2.plot(res.t, res.joint_angle[:, i], label=f"joint {i + 1}")
    a1.set_ylabel("tip deflection [mm]")
    a2.set_ylabel("joint angle [rad]")
    a2.set_xlabel("t [s]")
    for a in (a1, a2):
        a.grid(alpha=0.3)
        a.legend(loc="best", fontsize=8)
    a1.set_title(title)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return path


def run_simulate(a) -> int:
    try:
        case = load_case(a.case)
        res = simulate(case, elements_per_link=a.elements, h=a.h, integrator=a.integrator, sweep=a.sweep,
                       iterations=a.iterations, engine=a.engine, progress=True)
    except InputError as exc:
        print(f"dttmm: bad input: {exc}", file=sys.stderr)
        return 2
    except SimulationError as exc:
        print(f"dttmm: {exc}", file=sys.stderr)
        res = exc.partial
        if res is None:
            return 1
        print(f"dttmm: writing the partial result up to t = {res.t[-1] if res.t.size else 0:.6g} s", file=sys.stderr)
        code = 1
    else:
        code = 0
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    df = res.to_frame()
    table = out / f"{case.name or 'case'}.{a.format}"
    if a.format == "parquet":
        df.to_parquet(table)
    else:
        df.to_csv(table, index=False)
    meta = {k: v for k, v in res.meta.items()}
    meta.update(wall_time=res.wall_time, n_steps=res.n_steps, case=str(a.case))
    (out / "meta.json").write_text(json.dumps(meta, indent=2, default=str))
    png = plot_result(res, out / f"{case.name or 'case'}.png",
                      f"{case.name}: DT-TMM k = {a.elements}, h = {a.h:g} s ({a.integrator})")
    print(f"wrote {table}, {png}, {out / 'meta.json'}  (solve {res.wall_time:.3g} s, {res.n_steps} steps)")
    return code
