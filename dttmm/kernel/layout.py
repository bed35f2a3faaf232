"""The kernel's records: a constant :class:`Model` built once per discretised case and a
:class:`Data` workspace per run (the model/data split of Pinocchio), plus the named codes.

Rows are structured records (one per link, element or joint), so numba reads the fields by
name at the speed of a flat table, and a call passes a few arrays, not one per field. Elastic coordinates are *padded* to three per element, (u, v, φ): an inextensible link
gets a decoupled dummy u (unit effective mass, no coupling, zero load), so one code path
serves ne = 2 and ne = 3 links mixed in one arm; the dummy never enters q.

Symmetric 3×3 matrices that the sweeps carry between elements (articulated inertias P) are
stored packed, in the order of :data:`SYM` (00, 01, 02, 11, 12, 22).
"""
from __future__ import annotations

from typing import NamedTuple

import numpy as np

__all__ = ["Model", "Data", "LINK", "ELEMENT", "JOINT", "build_model", "make_data", "SYM"]

# --- codes shared by the driver and the kernel -----------------------------------------------
INT_NEWMARK, INT_RK4 = 0, 1              # integrator family
SW_RICCATI, SW_PLAIN = 0, 1              # sweep
IT_FIXED, IT_TOL, IT_AUTO = 0, 1, 2      # iteration control: m + 1 sweeps / tolerance / "auto"
# run status
ST_OK, ST_NONFINITE, ST_RUNAWAY, ST_SINGULAR = 0, 1, 2, 3
SWEEP_CODES = {"riccati": SW_RICCATI, "plain": SW_PLAIN}

#: index of (r, c) in a packed symmetric 3×3 matrix
SYM = ((0, 1, 2), (1, 3, 4), (2, 4, 5))

#: plain sweep: no pivot slot (the joint is motion-driven, its α̈ is known)
NO_SLOT = -1
#: elastic displacements beyond this many link lengths (rotations beyond this many rad) stop a run
RUNAWAY_LENGTHS, RUNAWAY_ANGLE = 10.0, 100.0


#: one row per link: the element moments (all integrals ∫ … ρA dx over one element, see
#: :mod:`dttmm.element`), padded to ne = 3, the rigid bodies and the coordinate layout
LINK = np.dtype([
    ("m", "f8"),                # element mass
    ("cs0", "f8", (2,)),        # ∫ s0
    ("CS", "f8", (2, 3)),       # ∫ S
    ("cs0s0", "f8"),            # ∫ s0·s0
    ("cs0S", "f8", (3,)),       # ∫ s0ᵀS
    ("d1", "f8", (3,)),         # ∫ s0ᵀEᵀS
    ("D2", "f8", (3, 3)),       # ∫ SᵀEᵀS
    ("CSS", "f8", (3, 3)),      # ∫ SᵀS (elastic mass)
    ("CSES", "f8", (3, 3)),     # ∫ SᵀES
    ("K", "f8", (3, 3)),        # linear stiffness
    ("D", "f8", (3, 3)),        # damping
    ("sO0", "f8", (2,)),        # s0 at the outboard node
    ("su", "f8"),               # axial entry of S_O (0 for an inextensible link)
    ("m_hub", "f8"), ("J_hub", "f8"),  # hub on the outboard side of joint i
    ("m_pay", "f8"), ("J_pay", "f8"),  # payload at the tip of link i
    ("dummy", "f8"),            # 1.0 for the padded dummy u of an inextensible link
    ("EA", "f8"), ("inv_l", "f8"), ("EAl", "f8"), ("G", "f8", (2, 2)),  # second-order strain: EA, 1/l, EA·l, G
    ("ne", "i8"),               # elastic coordinates per element (2 or 3)
    ("i_alpha", "i8"),          # index of α_i in q
    ("e_start", "i8"),          # index of the link's first elastic coordinate in q
    ("pad", "i8"),              # 3 − ne
    ("second_order", "?"),      # axial strain u/l + ½ wᵀGw
    ("motion", "?"),            # joint i is motion-driven
], align=True)

#: one row per element g = i·k + j: what the passes of a sweep hand to each other
ELEMENT = np.dtype([
    ("c", "f8"), ("s", "f8"), ("td", "f8"),  # frame cos θ, sin θ, θ̇
    ("e", "f8", (3,)), ("ed", "f8", (3,)),   # padded e, ė
    ("f_known", "f8", (3,)),   # K ê + D ê' (second-order strain: D ê' only)
    ("e_hat", "f8", (3,)),     # predictor ê (second-order strain)
    ("Ka", "f8", (3, 3)), ("k0", "f8", (3,)),  # Riccati gains: ë = Ka a_I + k0
    ("P", "f8", (6,)), ("c_I", "f8", (3,)),    # f = P a + c at the element root (P packed)
    ("rso", "f8", (2,)), ("gbar", "f8", (2,)),  # A s_O and γ̄_O
    ("a", "f8", (3,)),         # root acceleration
], align=True)

#: one row per joint i
JOINT = np.dtype([
    ("P_tip", "f8", (6,)), ("c_tip", "f8", (3,)),  # f = P a + c at the tip of link i
    ("P_hub", "f8", (6,)), ("c_hub", "f8", (3,)),  # ... on the outboard side of joint i
    ("ga", "f8", (3,)), ("g0", "f8"),              # α̈_i = ga·a + g0
    ("a_tip", "f8", (3,)),                         # tip acceleration of link i
    ("Mt", "f8", (3, 3)), ("cq", "f8"),            # M̃_ee = C_SS + c_q K + c_v D, and c_q
    ("subs", "f8", (4, 4)),    # plain sweep: w_before = S w_after at a torque-driven joint
    ("slot", "i8"),            # plain sweep: entry of w holding α̈_i, or NO_SLOT
    ("substituted", "?"),      # plain sweep: subs applies
], align=True)


class Model(NamedTuple):
    """Constants of the discretised arm (built once by :func:`build_model`)."""

    n: int                 # links
    k: int                 # elements per link
    grav: np.ndarray       # (2,) m/s²
    links: np.recarray     # (n,) of LINK
    im: np.ndarray         # (n_motion,) int: indices of the motion-driven α in q
    lim: np.ndarray        # (n_dof,) runaway bound per coordinate (inf for joint angles)


def build_model(st) -> Model:
    """Pack a :class:`dttmm.structure.Structure` into a :class:`Model`."""
    links = np.zeros(st.n_links, LINK).view(np.recarray)
    lim = np.full(st.n_dof, np.inf)
    for i, lk in enumerate(st.links):
        et, L = lk.et, links[i]
        p = 3 - et.ne
        _check_pattern(et)
        L.ne, L.pad, L.i_alpha, L.e_start, L.motion = et.ne, p, lk.i_alpha, lk.e_slice.start, st.motion[i]
        L.m, L.cs0s0, L.cs0, L.sO0 = et.m, et.c_s0s0, et.c_s0, et.sO0
        L.CS[:, p:] = et.C_S
        L.cs0S[p:], L.d1[p:] = et.c_s0S, et.d1
        for name, mat in (("D2", et.D2), ("CSS", et.C_SS), ("CSES", et.C_SES), ("K", et.K), ("D", et.D)):
            getattr(L, name)[p:, p:] = mat
        L.su = et.SO[0, 0] if et.ne == 3 else 0.0
        L.m_hub, L.J_hub, L.m_pay, L.J_pay = lk.m_hub, lk.M_hub[2, 2], lk.m_pay, lk.M_pay[2, 2]
        L.dummy = 1.0 if p else 0.0
        if et.second_order:
            L.second_order = True
            L.EA, L.inv_l, L.EAl, L.G = et.EA, 1.0 / et.l, et.EA * et.l, et.G
        el = np.full((lk.k, et.ne), RUNAWAY_LENGTHS * lk.length)
        el[:, et.iphi] = RUNAWAY_ANGLE
        lim[lk.e_slice] = el.ravel()
    ia = st.alpha_index.astype(np.int64)
    return Model(n=st.n_links, k=st.k, grav=np.ascontiguousarray(st.gravity, dtype=float), links=links,
                 im=np.ascontiguousarray(ia[st.motion]), lim=lim)


def _check_pattern(et) -> None:
    """The sweeps hard-code the sparsity of the element moments (u couples to (v, φ) only
    through D2 and C_SES) and the outboard shape S_O = [[s_u, 0, 0], [0, 1, 0]]: refuse anything
    else rather than compute it wrong."""
    p = 3 - et.ne
    SO = np.zeros((2, 3))
    SO[:, p:] = et.SO
    if not np.array_equal(SO, [[SO[0, 0], 0.0, 0.0], [0.0, 1.0, 0.0]]):  # pragma: no cover
        raise AssertionError("unexpected outboard shape matrix")
    pad3 = lambda a: np.pad(a, [(p, 0)] * a.ndim)
    CS = np.zeros((2, 3))
    CS[:, p:] = et.C_S
    zero = [et.c_s0[1], CS[0, 1], CS[0, 2], CS[1, 0], pad3(et.c_s0S)[1], pad3(et.c_s0S)[2], pad3(et.d1)[0]]
    for mat, entries in ((et.D2, ((0, 0), (1, 1), (1, 2), (2, 1), (2, 2))),
                         (et.C_SS, ((0, 1), (0, 2), (1, 0), (2, 0))),
                         (et.C_SES, ((0, 0), (1, 1), (1, 2), (2, 1), (2, 2))),
                         (et.K, ((0, 1), (0, 2), (1, 0), (2, 0))), (et.D, ((0, 1), (0, 2), (1, 0), (2, 0)))):
        full = pad3(mat)
        zero += [full[r, c] for r, c in entries]
    if np.any(np.asarray(zero) != 0.0):  # pragma: no cover
        raise AssertionError("unexpected element moment pattern")


class Data(NamedTuple):
    """Workspace of one run: element and joint records, and the plain sweep's arrays
    (allocated at full size only for that sweep)."""

    el: np.recarray        # (N,) of ELEMENT
    jt: np.recarray        # (n,) of JOINT
    cuts: np.ndarray       # plain: (n_cuts, 6, 4) the cut state z = B w at every cut
    E: np.ndarray          # plain: (N, 3, 7) ë = E (a_I, f_I, 1)


def make_data(md: Model, plain: bool = False) -> Data:
    """A zeroed workspace for ``md`` (the plain sweep's arrays tiny unless ``plain``)."""
    N = md.n * md.k
    return Data(el=np.zeros(N, ELEMENT).view(np.recarray), jt=np.zeros(md.n, JOINT).view(np.recarray),
                cuts=np.zeros((md.n * (md.k + 1) if plain else 1, 6, 4)), E=np.zeros((N if plain else 1, 3, 7)))
