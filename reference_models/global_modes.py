"""Natural frequencies of the global-equation solver's discretisation: K φ = ω² M φ with its
mass and stiffness matrices over the free coordinates (at rest, held joints clamped)."""

from __future__ import annotations

import numpy as np
import scipy.linalg

from dttmm.errors import InputError

from . import global_newmark as gm

__all__ = ["frequencies"]


def frequencies(case, elements_per_link: int, n: int | None = None) -> np.ndarray:
    """Lowest ``n`` natural frequencies (Hz) of ``case`` at rest from the global solver's M and K.

    Gravity would add stiffness terms that its constant K leaves out, so a case with gravity is
    refused (InputError naming ``model.gravity``).
    """
    if any(case.model.gravity):
        raise InputError("model.gravity", list(case.model.gravity), "the global solver's K is elastic only")
    k = elements_per_link
    names = gm.coordinate_names(case, k)
    q = np.zeros(len(names))
    alpha = [i for i, nm in enumerate(names) if nm.startswith("alpha_")]
    for i, d in zip(alpha, case.scenario.drives):
        q[i] = d.initial_angle
    held = [i for i, d in zip(alpha, case.scenario.drives) if d.kind == "motion"]
    free = np.setdiff1d(np.arange(len(names)), held)
    M = gm.mass_matrix(case, k, q)[np.ix_(free, free)]
    K = gm.stiffness_matrix(case, k)[np.ix_(free, free)]
    try:  # flexibility form: the lowest ω² are the largest 1/ω², computed to full accuracy
        lam = 1.0 / scipy.linalg.eigh(M, K, eigvals_only=True)[::-1]
    except np.linalg.LinAlgError:  # K singular (a free joint)
        lam = scipy.linalg.eigh(K, M, eigvals_only=True)
        lam = np.where(np.abs(lam) <= 1e-13 * np.abs(lam).max(), 0.0, lam)
    m = len(lam) if n is None else n
    return np.sqrt(np.maximum(lam[:m], 0.0)) / (2 * np.pi)
