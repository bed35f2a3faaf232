"""First simulation: load a shipped case, simulate it with DT-TMM, plot the tip deflection."""

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
from _gallery import CASES, QUICK, figure_path

import dttmm

case = dttmm.load_case(CASES / "single_link.toml")  # 1 m aluminium strip, bang-bang torque
res = dttmm.simulate(case, elements_per_link=4 if QUICK else 16, h=1e-3)
print(
    f"{res.status}: {res.n_steps} steps in {res.wall_time:.3f} s; final tip deflection {res.tip_deflection[-1, 0]:.3e} m"
)

fig, ax = plt.subplots(figsize=(6, 3))
ax.plot(res.t, 1e3 * res.tip_deflection[:, 0])
ax.set(xlabel="t [s]", ylabel="tip deflection [mm]", title="single_link, DT-TMM")
fig.tight_layout()
fig.savefig(figure_path("01_first_simulation.png"), dpi=100)
