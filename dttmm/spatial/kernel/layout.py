"""The records of the spatial kernel: :class:`Model` (constants of the discretised arm, one row
per link) and :class:`Work` (the workspace of the sweeps), named tuples of arrays.

Elastic coordinates are padded to six per element, (u, v, w, φx, φy, φz): an inextensible link
gets a decoupled dummy u (unit effective mass, no coupling, zero load) that never enters q.
Index 4 of the per-body tables is the outboard node (ξ = 1), 0…3 the Gauss points.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np


class Model(NamedTuple):
    n: int  # links
    nel: int  # elements in all
    ndof: int
    grav: np.ndarray  # (3,) world
    Rbase: np.ndarray  # (3, 3)
    pbase: np.ndarray  # (3,)
    k: np.ndarray  # (n,) elements of link i
    el0: np.ndarray  # (n,) index of its first element
    ext: np.ndarray  # (n,) 1: extensible
    so: np.ndarray  # (n,) 1: second-order strain
    locked: np.ndarray  # (n,) 1: locked joint
    motion: np.ndarray  # (n,) 1: motion-driven joint
    ia: np.ndarray  # (n,) index of α in q (-1: locked)
    ie: np.ndarray  # (nel,) index of the element's first elastic coordinate in q
    aF: np.ndarray  # (n, 3) joint axis in the element frame of the link's root
    aT: np.ndarray  # (n, 3) joint axis in the parent frame
    org: np.ndarray  # (n, 3) joint origin in the parent frame
    Crpy: np.ndarray  # (n, 3, 3) R_rpy of the joint origin
    axis: np.ndarray  # (n, 3) joint axis (joint frame)
    Q: np.ndarray  # (n, 3, 3) Rx(roll)
    hub_m: np.ndarray  # (n,)
    hub_J: np.ndarray  # (n, 3, 3) about the root, element-frame components
    pay_m: np.ndarray  # (n,)
    pay_d: np.ndarray  # (n, 3) centre, outboard element-frame components
    pay_J: np.ndarray  # (n, 3, 3) about the centre, outboard element-frame components
    l: np.ndarray  # (n,) element length
    K: np.ndarray  # (n, 6, 6) linear stiffness (padded)
    Kb: np.ndarray  # (n, 6, 6) K without the axial term
    EA: np.ndarray  # (n,)
    mu: np.ndarray  # (n,) Kelvin-Voigt coefficient
    G: np.ndarray  # (n, 2, 2) ∫₀¹ N'ᵀN' dξ
    s0: np.ndarray  # (n, 5, 3) undeformed local positions of the bodies
    Sig: np.ndarray  # (n, 5, 3, 6) ∂s/∂e
    Psi: np.ndarray  # (n, 5, 3, 6) ∂ψ/∂e
    mg: np.ndarray  # (n, 4) masses of the Gauss bodies
    Ig: np.ndarray  # (n, 4, 3) principal inertias of the Gauss bodies
    mel: np.ndarray  # (n,) element mass Σ m_g
    CS: np.ndarray  # (n, 3, 6) Σ m_g Σ_g
    CSS: np.ndarray  # (n, 6, 6) Σ m_g Σ_gᵀ Σ_g


class Work(NamedTuple):
    """Kinematics at the iterate and what the backward sweep leaves for the forward one."""

    Rw: np.ndarray  # (nel, 3, 3) element frames (world)
    pw: np.ndarray  # (nel, 3) element frame origins
    vl: np.ndarray  # (nel, 3) origin velocity, frame components
    wl: np.ndarray  # (nel, 3) angular velocity, frame components
    E: np.ndarray  # (nel, 3, 3) exp(φ): next frame in this one
    e: np.ndarray  # (nel, 6) padded elastic coordinates
    ed: np.ndarray  # (nel, 6)
    RT: np.ndarray  # (n + 1, 3, 3) parent frame of joint i (n: the last link's tip frame)
    pT: np.ndarray  # (n + 1, 3)
    vT: np.ndarray  # (n + 1, 3)
    wT: np.ndarray  # (n + 1, 3)
    C: np.ndarray  # (n, 3, 3) root element frame in the parent frame
    Ka: np.ndarray  # (nel, 6, 6) ë = Ka A + k0
    k0: np.ndarray  # (nel, 6)
    XS: np.ndarray  # (nel, 6, 12) outboard maps [X_O | S_O]
    zO: np.ndarray  # (nel, 6)
    Pc: np.ndarray  # (nel, 6, 7) articulated inertia and bias at each element root (loads)
    Ptip: np.ndarray  # (n, 6, 7) at each link tip (outboard element-frame components)
    PF: np.ndarray  # (n, 6, 7) at each link root with the hub, before the joint
    zJ: np.ndarray  # (n, 6) joint velocity-product term (root frame components)
    acc: np.ndarray  # (n, 3) per joint: α̈, torque, α̇
    slope: np.ndarray  # (n,) per torque joint: ∂τ/∂α̈ of a closed-loop law (0: open loop)
    wdF: np.ndarray  # (n, 3) angular acceleration of each link root (root element frame)
    # scratch of the element step (no allocation per element)
    H: np.ndarray  # (3, 12) angular velocity map of a body, [0, I, J_L Ψ]
    B: np.ndarray  # (3, 12) its inertia times H
    M12: np.ndarray  # (12, 12) the element's matrix over (A, ë)
    r12: np.ndarray  # (12,)
    PW: np.ndarray  # (6, 12)
    Pr: np.ndarray  # (6, 6) the outboard P in this element's frame
    cr: np.ndarray  # (6,)
    L: np.ndarray  # (6, 6) Cholesky factor
    sol: np.ndarray  # (6, 7)
    E3: np.ndarray  # (3, 3)
    J3: np.ndarray  # (3, 3)
    jd3: np.ndarray  # (3,)
    Iw: np.ndarray  # (3, 3)
    P: np.ndarray  # (6, 6) the running articulated inertia
    c: np.ndarray  # (6,)
    KT: np.ndarray  # (6, 6)
    D6: np.ndarray  # (6, 6)
    f6: np.ndarray  # (6,)
    A6: np.ndarray  # (6,)
    A6b: np.ndarray  # (6,)
