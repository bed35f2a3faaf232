"""Every golden value the tests compare against, with its source and the date it was recorded.

A golden value is a number measured with another, independent computation (another engine,
a published benchmark) rather than derived in the test from a closed form. Change one only
with a new measurement: edit its ``source`` and ``date`` with it. The values measured with
Exudyn are recomputed by ``python -m tests.golden`` (prints each beside the stored value).
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class Golden:
    value: float
    unit: str
    source: str
    date: str


GOLDEN = {
    # Kane-Ryan-Banerjee spin-up beam (experiments/cases/spin_up.toml, 20 s)
    "spin_up.peak_tip_deflection": Golden(
        0.400147,
        "m",
        "Exudyn ANCF (reference_models.exudyn_ancf), k = 64, h = 5e-3 s: max |tip deflection| over "
        "the 20 s, at t = 6.95 s (h = 2.5e-3 s: 0.400124)",
        "2026-12-01",
    ),
    "spin_up.tip_deflection_after_16s": Golden(
        0.004073,
        "m",
        "Exudyn ANCF, k = 64, h = 5e-3 s: max |tip deflection| for t > 16 s (after the spin-up)",
        "2026-12-01",
    ),
    # experiments/cases/single_link.toml (bang-bang torque, 2 s)
    "single_link.peak_tip_deflection": Golden(
        0.34195,
        "m",
        "Exudyn ANCF, k = 64, h = 1e-3 s: max |tip deflection| over the 2 s, at t = 0.622 s "
        "(k = 16: 0.341929, k = 32: 0.341949; k = 64, h = 5e-4 s: 0.341958)",
        "2026-12-01",
    ),
    # experiments/cases/control/closed_loop_three_link.toml, 4 s, the same moment_gain on every
    # joint; docs/control.md, "Measured with mujoco-chain" (k = 8, h = 1e-4 s, the same to 4
    # digits at h = 5e-5 s)
    "closed_loop.peak_w1_gain0": Golden(
        14.7e-3, "m", "MuJoCo chain, k = 8, h = 1e-4 s, moment_gain 0", "2026-11"
    ),
    "closed_loop.peak_w1_gain4": Golden(
        6.4e-3, "m", "MuJoCo chain, k = 8, h = 1e-4 s, moment_gain 4", "2026-11"
    ),
    "closed_loop.decay_gain0": Golden(
        1.49, "1/s", "MuJoCo chain, k = 8, h = 1e-4 s, moment_gain 0", "2026-11"
    ),
    "closed_loop.decay_gain4": Golden(
        0.50, "1/s", "MuJoCo chain, k = 8, h = 1e-4 s, moment_gain 4", "2026-11"
    ),
}


def value(name: str) -> float:
    """The stored value of golden ``name``."""
    return GOLDEN[name].value


def _measure() -> dict[str, float]:
    """The Exudyn-measured values, recomputed (minutes of CPU)."""
    import numpy as np

    import dttmm
    from reference_models import exudyn_ancf

    spin = dttmm.load_case("experiments/cases/spin_up.toml")
    r = exudyn_ancf.simulate(spin, elements_per_link=64, h=5e-3)
    v = r.tip_deflection[:, 0]
    single = dttmm.load_case("experiments/cases/single_link.toml")
    s = exudyn_ancf.simulate(single, elements_per_link=64, h=1e-3)
    return {
        "spin_up.peak_tip_deflection": float(np.max(np.abs(v))),
        "spin_up.tip_deflection_after_16s": float(np.max(np.abs(v[r.t > 16]))),
        "single_link.peak_tip_deflection": float(np.max(np.abs(s.tip_deflection[:, 0]))),
    }


if __name__ == "__main__":
    for name, got in _measure().items():
        print(f"{name}: stored {GOLDEN[name].value:.6g}, measured now {got:.6g}")
