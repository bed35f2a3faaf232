"""The records of the spatial kernel: :class:`Model` (constants of the discretised arm, one row
per link) and :class:`Work` (the workspace of the sweeps), named tuples of arrays.

Elastic coordinates are padded to six per element, (u, v, w, φx, φy, φz): an inextensible link
gets a decoupled dummy u (unit effective mass, no coupling, zero load) that never enters q.
Index 4 of the per-body tables is the outboard node (ξ = 1), 0…3 the Gauss points.
A rigid link keeps its k element slots as rigid segments of length L/k (no coordinates, e ≡ 0,
exp(φ) = I): its body enters at the root slot (docs/spatial.md §5, "Rigid links").
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
    rigid: np.ndarray  # (n,) 1: rigid link (its k slots are rigid segments of length l, no e)
    rb_m: np.ndarray  # (n,) a rigid link's mass
    rb_c: np.ndarray  # (n, 3) its centre of mass (link frame)
    rb_J: np.ndarray  # (n, 3, 3) its inertia about the centre of mass (link frame)
    par: np.ndarray  # (n,) index of the parent link (−1: the base); parents come first


class Work(NamedTuple):
    """Kinematics at the iterate and what the backward sweep leaves for the forward one."""

    Rw: np.ndarray  # (nel, 3, 3) element frames (world)
    pw: np.ndarray  # (nel, 3) element frame origins
    vl: np.ndarray  # (nel, 3) origin velocity, frame components
    wl: np.ndarray  # (nel, 3) angular velocity, frame components
    E: np.ndarray  # (nel, 3, 3) exp(φ): next frame in this one
    JO: np.ndarray  # (nel, 3, 3) J_L(φ) of the outboard node
    jdO: np.ndarray  # (nel, 3) J̇_L φ̇ of the outboard node
    sO: np.ndarray  # (nel, 3) outboard node position, element frame components
    e: np.ndarray  # (nel, 6) padded elastic coordinates
    ed: np.ndarray  # (nel, 6)
    RT: np.ndarray  # (n + 1, 3, 3) 0: the base frame; i + 1: the tip frame of link i
    pT: np.ndarray  # (n + 1, 3)
    vT: np.ndarray  # (n + 1, 3)
    wT: np.ndarray  # (n + 1, 3)
    C: np.ndarray  # (n, 3, 3) root element frame in the parent frame
    Lc: np.ndarray  # (nel, 6, 6) Cholesky factor L of M_ee (lower; 1/L_jj on the diagonal)
    Y: np.ndarray  # (nel, 6, 7) L⁻¹ [M_eA | r_e]: ë = −L⁻ᵀ (Y [A; 1])
    zO: np.ndarray  # (nel, 6) velocity-product acceleration of the outboard node
    Pc: np.ndarray  # (nel, 6, 7) articulated inertia and bias at each element root (loads)
    Ptip: np.ndarray  # (n, 6, 7) at each link tip (outboard element-frame components)
    PF: np.ndarray  # (n, 6, 7) at each link root with the hub, before the joint
    zJ: np.ndarray  # (n, 6) joint velocity-product term (root frame components)
    acc: np.ndarray  # (n, 3) per joint: α̈, torque, α̇
    slope: np.ndarray  # (n,) per torque joint: ∂τ/∂α̈ of a closed-loop law (0: open loop)
    wdF: np.ndarray  # (n, 3) angular acceleration of each link root (root element frame)
    Pacc: np.ndarray  # (n + 1, 6, 7) the children's (P, c) summed in each tip frame (0: base)
    nacc: np.ndarray  # (n + 1,) how many children have added to Pacc
    Atip: np.ndarray  # (n + 1, 6) acceleration of each tip frame (0: the base, at rest)
    # scratch of the sweeps and the kinematics (nothing is allocated per call)
    M12: np.ndarray  # (12, 12) the element's matrix over (A, ë), upper triangle
    r12: np.ndarray  # (12,)
    E3: np.ndarray  # (3, 3)
    J3: np.ndarray  # (3, 3)
    jd3: np.ndarray  # (3,)
    Iw: np.ndarray  # (3, 3)
    IJ: np.ndarray  # (3, 3)
    N3: np.ndarray  # (3, 3)
    Cs: np.ndarray  # (3, 3)
    rho: np.ndarray  # (6,)
    P: np.ndarray  # (6, 6) the running articulated inertia
    c: np.ndarray  # (6,)
    KT: np.ndarray  # (6, 6)
    D6: np.ndarray  # (6, 6)
    f6: np.ndarray  # (6,)
    eh: np.ndarray  # (6,)
    edh: np.ndarray  # (6,)
    fx: np.ndarray  # (6,)
    Ps: np.ndarray  # (6,)
    A6: np.ndarray  # (6,)
    A6b: np.ndarray  # (6,)
    Rk: np.ndarray  # (3, 3)
    Tk: np.ndarray  # (3, 3)
    Uk: np.ndarray  # (3, 3)
    pk: np.ndarray  # (3,)
    vk: np.ndarray  # (3,)
    wk: np.ndarray  # (3,)
