"""The kernel's records: a constant :class:`Model` built once per discretised case and a
:class:`Data` workspace per run (the model/data split of Pinocchio), plus the named codes.

Both are named tuples of arrays (structure of arrays), so numba reads the fields by name at
the speed of a flat table (measured: records with named fields were ~2× slower). Elastic
coordinates are *padded* to three per element, (u, v, φ): an inextensible link
gets a decoupled dummy u (unit effective mass, no coupling, zero load), so one code path
serves ne = 2 and ne = 3 links mixed in one arm; the dummy never enters q.

Symmetric 3×3 matrices that the sweeps carry between elements (articulated inertias P) are
stored packed, in the order of :data:`SYM` (00, 01, 02, 11, 12, 22).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

__all__ = ["SYM", "Data", "Model", "build_model", "make_data"]

# --- codes shared by the driver and the kernel -----------------------------------------------
INT_NEWMARK, INT_RK4 = 0, 1  # integrator family
SW_RICCATI, SW_PLAIN = 0, 1  # sweep
IT_FIXED, IT_TOL, IT_AUTO = 0, 1, 2  # iteration control: m + 1 sweeps / tolerance / "auto"
# run status
ST_OK, ST_NONFINITE, ST_RUNAWAY, ST_SINGULAR = 0, 1, 2, 3
SWEEP_CODES = {"riccati": SW_RICCATI, "plain": SW_PLAIN}

#: index of (r, c) in a packed symmetric 3×3 matrix
SYM = ((0, 1, 2), (1, 3, 4), (2, 4, 5))

#: plain sweep: no pivot slot (the joint is motion-driven, its α̈ is known)
NO_SLOT = -1
#: an element's elastic displacement u or v beyond this many element lengths, or its elastic
#: rotation φ beyond this many rad, stops a run: no beam deforms like that, the state is diverging.
#: The u of a second-order strain element also carries the bending foreshortening ½∫w'² dx,
#: which reaches element lengths when an element bends by radians: its bound is looser.
RUNAWAY_LENGTHS, RUNAWAY_ANGLE, RUNAWAY_LENGTHS_U2 = 2.0, 2.0 * np.pi, 10.0


class Model(NamedTuple):
    """Constants of the discretised arm, one row per link (element moments padded to ne = 3;
    all integrals ∫ … ρA dx over one element, see :mod:`dttmm.element`)."""

    n: int  # links
    k: int  # elements per link
    grav: np.ndarray  # (2,) m/s²
    m: np.ndarray  # (n,) element mass
    cs0: np.ndarray  # (n, 2) ∫ s0
    CS: np.ndarray  # (n, 2, 3) ∫ S
    cs0s0: np.ndarray  # (n,) ∫ s0·s0
    cs0S: np.ndarray  # (n, 3) ∫ s0ᵀS
    d1: np.ndarray  # (n, 3) ∫ s0ᵀEᵀS
    D2: np.ndarray  # (n, 3, 3) ∫ SᵀEᵀS
    CSS: np.ndarray  # (n, 3, 3) ∫ SᵀS (elastic mass)
    CSES: np.ndarray  # (n, 3, 3) ∫ SᵀES
    K: np.ndarray  # (n, 3, 3) linear stiffness
    D: np.ndarray  # (n, 3, 3) damping
    sO0: np.ndarray  # (n, 2) s0 at the outboard node
    su: np.ndarray  # (n,) axial entry of S_O (0 for an inextensible link)
    m_hub: np.ndarray  # (n,) hub mass and inertia (outboard side of joint i)
    J_hub: np.ndarray
    m_pay: np.ndarray  # (n,) payload mass and inertia (tip of link i)
    J_pay: np.ndarray
    dummy: np.ndarray  # (n,) 1.0 for the padded dummy u of an inextensible link
    rigid: np.ndarray  # (n,) bool: a rigid link (ne = 0; its k element slots are rigid massless
    #                    segments of length sO0[i, 0] = L/k, its body at the root)
    body: np.ndarray  # (n, 4) rigid link's body: mass, centre of mass (x, y) in the link frame,
    #                   inertia about the centre of mass
    pay_off: np.ndarray  # (n, 2) payload's centre of mass in the tip frame
    pay_offset: np.ndarray  # (n,) bool: the payload's centre of mass is off the tip
    second_order: np.ndarray  # (n,) bool: axial strain u/l + ½ wᵀGw
    EA: np.ndarray  # (n,) second-order strain constants: EA, 1/l, EA·l, G (2, 2)
    inv_l: np.ndarray
    EAl: np.ndarray
    G: np.ndarray
    mu: np.ndarray  # (n,) Kelvin-Voigt μ (s) of a second-order link (0 otherwise)
    ne: np.ndarray  # (n,) int: elastic coordinates per element (2 or 3)
    i_alpha: np.ndarray  # (n,) int: index of α_i in q
    e_start: np.ndarray  # (n,) int: index of the link's first elastic coordinate in q
    pad: np.ndarray  # (n,) int: 3 − ne
    motion: np.ndarray  # (n,) bool: joint i is motion-driven
    im: np.ndarray  # (n_motion,) int: indices of the motion-driven α in q
    lim: np.ndarray  # (n_dof,) runaway bound per coordinate (inf for joint angles)


def build_model(structure) -> Model:
    """Pack a :class:`dttmm.structure.Structure` into a :class:`Model`."""
    n = structure.n_links
    z = lambda *shape: np.zeros((n, *shape))
    f = {
        name: z()
        for name in (
            "m",
            "cs0s0",
            "su",
            "m_hub",
            "J_hub",
            "m_pay",
            "J_pay",
            "dummy",
            "EA",
            "inv_l",
            "EAl",
            "mu",
        )
    }
    f.update(
        cs0=z(2),
        CS=z(2, 3),
        cs0S=z(3),
        d1=z(3),
        D2=z(3, 3),
        CSS=z(3, 3),
        CSES=z(3, 3),
        K=z(3, 3),
        D=z(3, 3),
        sO0=z(2),
        G=z(2, 2),
    )
    ne, pad = np.zeros(n, np.int64), np.zeros(n, np.int64)
    second_order = np.zeros(n, np.bool_)
    rigid, pay_offset = np.zeros(n, np.bool_), np.zeros(n, np.bool_)
    body, pay_off = np.zeros((n, 4)), np.zeros((n, 2))
    lim = np.full(structure.n_dof, np.inf)
    for i, lk in enumerate(structure.links):
        f["m_hub"][i], f["J_hub"][i] = lk.m_hub, lk.M_hub[2, 2]
        f["m_pay"][i], f["J_pay"][i] = lk.m_pay, lk.M_pay[2, 2]
        pay_off[i] = lk.pay_offset
        pay_offset[i] = any(x != 0.0 for x in lk.pay_offset)
        if lk.rigid:
            rigid[i] = True
            ne[i], pad[i] = 0, 3
            body[i] = lk.body
            f["sO0"][i, 0] = lk.length / lk.k
            f["dummy"][i] = 1.0
            continue
        et = lk.et
        p = 3 - et.ne
        ne[i], pad[i] = et.ne, p
        SO = np.zeros((2, 3))
        SO[:, p:] = et.SO
        if not np.array_equal(SO, [[SO[0, 0], 0.0, 0.0], [0.0, 1.0, 0.0]]):  # pragma: no cover
            raise AssertionError("unexpected outboard shape matrix")
        f["m"][i], f["cs0s0"][i] = et.m, et.c_s0s0
        f["cs0"][i], f["sO0"][i] = et.c_s0, et.sO0
        f["CS"][i, :, p:] = et.C_S
        f["cs0S"][i, p:], f["d1"][i, p:] = et.c_s0S, et.d1
        for name, mat in (("D2", et.D2), ("CSS", et.C_SS), ("CSES", et.C_SES), ("K", et.K), ("D", et.D)):
            f[name][i, p:, p:] = mat
        f["su"][i] = et.SO[0, 0] if et.ne == 3 else 0.0
        f["dummy"][i] = 1.0 if p else 0.0
        _check_pattern(f, i)
        if et.second_order:
            second_order[i] = True
            f["EA"][i], f["inv_l"][i], f["EAl"][i] = et.EA, 1.0 / et.l, et.EA * et.l
            f["G"][i] = et.G
            f["mu"][i] = et.mu
        el = np.full((lk.k, et.ne), RUNAWAY_LENGTHS * lk.length / lk.k)
        el[:, et.iphi] = RUNAWAY_ANGLE
        if et.second_order and et.ne == 3:
            el[:, 0] = RUNAWAY_LENGTHS_U2 * lk.length / lk.k
        lim[lk.e_slice] = el.ravel()
    ia = structure.alpha_index.astype(np.int64)
    return Model(
        n=n,
        k=structure.k,
        grav=np.ascontiguousarray(structure.gravity, dtype=float),
        ne=ne,
        i_alpha=ia,
        e_start=np.array([lk.e_slice.start for lk in structure.links], np.int64),
        pad=pad,
        motion=structure.motion.astype(np.bool_),
        im=np.ascontiguousarray(ia[structure.motion]),
        lim=lim,
        second_order=second_order,
        rigid=rigid,
        body=body,
        pay_off=pay_off,
        pay_offset=pay_offset,
        **f,
    )


def _check_pattern(f: dict, i: int) -> None:
    """The sweeps hard-code the sparsity of the element moments (u couples to (v, φ) only
    through D2 and C_SES) and the outboard shape S_O = [[s_u, 0, 0], [0, 1, 0]]: refuse anything
    else rather than compute it wrong. ``f``: the padded fields of :func:`build_model`."""
    zero = [
        f["cs0"][i, 1],
        f["CS"][i, 0, 1],
        f["CS"][i, 0, 2],
        f["CS"][i, 1, 0],
        f["cs0S"][i, 1],
        f["cs0S"][i, 2],
        f["d1"][i, 0],
    ]
    for name, entries in (
        ("D2", ((0, 0), (1, 1), (1, 2), (2, 1), (2, 2))),
        ("CSS", ((0, 1), (0, 2), (1, 0), (2, 0))),
        ("CSES", ((0, 0), (1, 1), (1, 2), (2, 1), (2, 2))),
        ("K", ((0, 1), (0, 2), (1, 0), (2, 0))),
        ("D", ((0, 1), (0, 2), (1, 0), (2, 0))),
    ):
        zero += [f[name][i, r, c] for r, c in entries]
    if any(z != 0.0 for z in zero):  # pragma: no cover
        raise AssertionError("unexpected element moment pattern")


class Data(NamedTuple):
    """Workspace of one run: what the passes of a sweep hand to each other.

    Per element g = i·k + j (link i, element j): frame cos/sin and rate, padded e and ė, the
    known elastic force K ê + D ê' (linear strain; D ê' only for second-order strain, whose
    predictors ê, ê' are kept in ``e_hat``), the Riccati gains (ë = Ka a_I + k0), the articulated
    inertia P (packed) and bias c_I at the element root, A s_O, γ̄_O and the root acceleration.
    Per joint i: P and c at the link tip and at the hub, the joint gains α̈ = ga·a + g0, the
    tip acceleration, the effective elastic mass M̃_ee, c_q and c_v. The plain sweep's arrays are
    allocated at full size only for that sweep.
    """

    c: np.ndarray  # (N,)
    s: np.ndarray  # (N,)
    td: np.ndarray  # (N,)
    e: np.ndarray  # (N, 3)
    ed: np.ndarray  # (N, 3)
    f_known: np.ndarray  # (N, 3)
    e_hat: np.ndarray  # (N, 6) ê, ê' of second-order links
    Ka: np.ndarray  # (N, 3, 3)
    k0: np.ndarray  # (N, 3)
    P: np.ndarray  # (N, 6) packed symmetric
    c_I: np.ndarray  # (N, 3)
    rso: np.ndarray  # (N, 2)
    gbar: np.ndarray  # (N, 2)
    a: np.ndarray  # (N, 3)
    P_tip: np.ndarray  # (n, 6)
    c_tip: np.ndarray  # (n, 3)
    P_hub: np.ndarray  # (n, 6)
    c_hub: np.ndarray  # (n, 3)
    ga: np.ndarray  # (n, 3)
    g0: np.ndarray  # (n,)
    a_tip: np.ndarray  # (n, 3)
    Mt: np.ndarray  # (n, 3, 3)
    cq: np.ndarray  # (n, 2) c_q, c_v
    cuts: np.ndarray  # plain: (n_cuts, 6, 4) the cut state z = B w at every cut
    E: np.ndarray  # plain: (N, 3, 7) ë = E (a_I, f_I, 1)
    subs: np.ndarray  # plain: (n, 4, 4) joint substitutions w_before = S w_after
    substituted: np.ndarray  # plain: (n,) bool
    slot: np.ndarray  # plain: (n,) int: entry of w holding α̈_i, or NO_SLOT


def make_data(md: Model, plain: bool = False) -> Data:
    """A zeroed workspace for ``md`` (the plain sweep's arrays tiny unless ``plain``)."""
    n, N = md.n, md.n * md.k
    ncuts = n * (md.k + 1) if plain else 1
    return Data(
        c=np.zeros(N),
        s=np.zeros(N),
        td=np.zeros(N),
        e=np.zeros((N, 3)),
        ed=np.zeros((N, 3)),
        f_known=np.zeros((N, 3)),
        e_hat=np.zeros((N, 6)),
        Ka=np.zeros((N, 3, 3)),
        k0=np.zeros((N, 3)),
        P=np.zeros((N, 6)),
        c_I=np.zeros((N, 3)),
        rso=np.zeros((N, 2)),
        gbar=np.zeros((N, 2)),
        a=np.zeros((N, 3)),
        P_tip=np.zeros((n, 6)),
        c_tip=np.zeros((n, 3)),
        P_hub=np.zeros((n, 6)),
        c_hub=np.zeros((n, 3)),
        ga=np.zeros((n, 3)),
        g0=np.zeros(n),
        a_tip=np.zeros((n, 3)),
        Mt=np.zeros((n, 3, 3)),
        cq=np.zeros((n, 2)),
        cuts=np.zeros((ncuts, 6, 4)),
        E=np.zeros((N if plain else 1, 3, 7)),
        subs=np.zeros((n, 4, 4)),
        substituted=np.zeros(n, np.bool_),
        slot=np.zeros(n, np.int64),
    )
