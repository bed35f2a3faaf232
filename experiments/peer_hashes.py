"""sha256 of every Result array of the spatial MuJoCo chain and Pinocchio's rigid spatial model on
every shipped serial spatial case (k = 2, 0.02 s): the check that a change to those peers leaves
their chain results bit for bit as they were.

    python -m experiments.peer_hashes > before.json   # then, after the change:
    python -m experiments.peer_hashes | diff before.json -
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import sys
from pathlib import Path

import numpy as np

import dttmm

CASES = Path(__file__).resolve().parent / "cases" / "spatial"


def _hashes(res) -> dict:
    out = {}
    for f in dataclasses.fields(res):
        v = getattr(res, f.name)
        if isinstance(v, np.ndarray):
            out[f.name] = hashlib.sha256(np.ascontiguousarray(v).tobytes()).hexdigest()
    return out


def main() -> dict:
    from reference_models import mujoco_spatial, pinocchio_spatial

    out = {}
    for path in sorted(CASES.rglob("*.toml")):
        case = dttmm.load_case(path)
        if not case.model.serial:
            continue
        sc = dataclasses.replace(case.scenario, duration=0.02, output_step=2e-3)
        case = dataclasses.replace(case, scenario=sc)
        name = str(path.relative_to(CASES))
        runs = {
            "mujoco-spatial": lambda c: mujoco_spatial.simulate(c, elements_per_link=2, h=2.5e-4),
            "pinocchio-spatial": lambda c: pinocchio_spatial.simulate(c, h=1e-3),
            "pinocchio-spatial-newmark": lambda c: pinocchio_spatial.simulate(
                c, h=1e-3, integrator="newmark"
            ),
        }
        for method, run in runs.items():
            try:
                res = run(case)
            except dttmm.InputError as e:
                out[f"{name} {method}"] = f"refused: {e}"
                continue
            except dttmm.SimulationError as e:
                res = e.partial
            except Exception as e:  # noqa: BLE001 (an error is recorded as it is, for the diff)
                out[f"{name} {method}"] = f"error: {type(e).__name__}: {e}"
                continue
            out[f"{name} {method}"] = _hashes(res)
    return out


if __name__ == "__main__":
    json.dump(main(), sys.stdout, indent=1, sort_keys=True)
    sys.stdout.write("\n")
