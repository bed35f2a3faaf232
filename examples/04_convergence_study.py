"""Convergence study: refine the mesh k against a fine DT-TMM reference and fit the observed
order from log(error) against log(k)."""

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
from _gallery import CASES, QUICK, figure_path

import dttmm
from experiments.metrics import errors

case = dttmm.load_case(CASES / "single_link.toml")
T = 0.3 if QUICK else 1.0
case = dttmm.Case(case.model, dttmm.Scenario(T, 1e-3, case.scenario.drives), case.name)
ks = [1, 2, 4] if QUICK else [1, 2, 4, 8, 16]
ref = dttmm.simulate(case, elements_per_link=2 * ks[-1] if QUICK else 64, h=1e-3)
err = [errors(dttmm.simulate(case, elements_per_link=k, h=1e-3), ref)["ee_l2"] for k in ks]
order = -np.polyfit(np.log(ks), np.log(err), 1)[0]
print("k:", ks, "end-effector RMS error [m]:", [f"{e:.2e}" for e in err], f"observed order {order:.2f}")

fig, ax = plt.subplots(figsize=(4.5, 3.2))
ax.loglog(ks, err, "o-", label=f"DT-TMM (order {order:.2f})")
ax.set(xlabel="elements per link k", ylabel="end-effector error (RMS) [m]")
ax.legend()
fig.tight_layout()
fig.savefig(figure_path("04_convergence.png"), dpi=100)
