"""The discretised spatial arm: coordinates and the constants of :class:`kernel.layout.Model`
(docs/spatial.md §2), built once per run."""

from __future__ import annotations

import numpy as np

from ..errors import InputError
from .kernel.layout import Model, Work
from .model import SpatialManipulator
from .rotation import rpy_matrix

__all__ = ["STRAINS", "build_model", "make_work", "gauss_points"]

STRAINS = ("linear", "second-order")


def gauss_points():
    """(ξ (4,), weights (4,)) of the 4-point Gauss–Legendre rule on [0, 1]."""
    xg, wg = np.polynomial.legendre.leggauss(4)
    return 0.5 * (xg + 1.0), 0.5 * wg


def rx(angle: float) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def shape_tables(l: float, extensible: bool, xi):
    """s0 (m, 3), Σ = ∂s/∂e (m, 3, 6) and Ψ = ∂ψ/∂e (m, 3, 6) at the points ξ (padded e)."""
    xi = np.asarray(xi, float)
    m = xi.size
    n3 = 3 * xi**2 - 2 * xi**3
    n4 = l * (xi**3 - xi**2)
    d3 = (6 * xi - 6 * xi**2) / l if l > 0 else np.zeros_like(xi)  # dN3/dx (l = 0: a rigid link's)
    d4 = 3 * xi**2 - 2 * xi  # dN4/dx
    s0 = np.zeros((m, 3))
    s0[:, 0] = xi * l
    sig = np.zeros((m, 3, 6))
    if extensible:
        sig[:, 0, 0] = xi
    sig[:, 1, 1] = n3
    sig[:, 1, 5] = n4
    sig[:, 2, 2] = n3
    sig[:, 2, 4] = -n4
    psi = np.zeros((m, 3, 6))
    psi[:, 0, 3] = xi
    psi[:, 1, 2] = -d3
    psi[:, 1, 4] = d4
    psi[:, 2, 1] = d3
    psi[:, 2, 5] = d4
    return s0, sig, psi


def stiffness(beam, l: float) -> np.ndarray:
    """The padded 6×6 linear stiffness of one element (docs/spatial.md §2)."""
    K = np.zeros((6, 6))
    if beam.EA is not None:
        K[0, 0] = beam.EA / l
    K[3, 3] = beam.GJ / l
    kz = beam.EIz / l**3 * np.array([[12.0, -6.0 * l], [-6.0 * l, 4.0 * l * l]])
    ky = beam.EIy / l**3 * np.array([[12.0, 6.0 * l], [6.0 * l, 4.0 * l * l]])
    K[np.ix_([1, 5], [1, 5])] = kz
    K[np.ix_([2, 4], [2, 4])] = ky
    return K


#: where the padded stiffness may be nonzero: u, φx and the (v, φz), (w, φy) bending pairs
STIFFNESS_PATTERN = np.zeros((6, 6), bool)
STIFFNESS_PATTERN[0, 0] = STIFFNESS_PATTERN[3, 3] = True
STIFFNESS_PATTERN[np.ix_([1, 5], [1, 5])] = STIFFNESS_PATTERN[np.ix_([2, 4], [2, 4])] = True


def pattern_ok(sig, psi, s0) -> bool:
    """Whether the shape tables (m, 3, 6) have the pattern the kernel's element step assumes:
    s0 on the axis; Σ: u → x (su), v → y and w → z (n3), φz → y (n4), φy → z (−n4); Ψ: φx → x
    (px), v → z and w → y (±d3), φy → y and φz → z (d4); nothing else."""
    rebuilt_sig = np.zeros_like(sig)
    rebuilt_psi = np.zeros_like(psi)
    n3, n4, d3, d4 = sig[:, 1, 1], sig[:, 1, 5], psi[:, 2, 1], psi[:, 2, 5]
    rebuilt_sig[:, 0, 0] = sig[:, 0, 0]
    rebuilt_sig[:, 1, 1] = rebuilt_sig[:, 2, 2] = n3
    rebuilt_sig[:, 1, 5] = n4
    rebuilt_sig[:, 2, 4] = -n4
    rebuilt_psi[:, 0, 3] = psi[:, 0, 3]
    rebuilt_psi[:, 2, 1] = d3
    rebuilt_psi[:, 1, 2] = -d3
    rebuilt_psi[:, 1, 4] = rebuilt_psi[:, 2, 5] = d4
    return np.array_equal(sig, rebuilt_sig) and np.array_equal(psi, rebuilt_psi) and not np.any(s0[:, 1:])


def g_matrix(l: float) -> np.ndarray:
    if l == 0.0:
        return np.zeros((2, 2))
    xi, w = gauss_points()
    dN = np.stack([(6 * xi - 6 * xi**2) / l, 3 * xi**2 - 2 * xi], axis=-1)
    return np.einsum("m,mi,mj->ij", w, dN, dN)


def build_model(manip: SpatialManipulator, k: int, strain: str = "linear", motion=None) -> Model:
    """Constants of the arm with k elements per link; ``motion`` (n,) flags the motion-driven
    joints (unlocked links only)."""
    if not isinstance(manip, SpatialManipulator):
        raise InputError("model", manip, "must be a dttmm.spatial.SpatialManipulator")
    n = manip.n_links
    motion = np.zeros(n, np.int64) if motion is None else np.asarray(motion, np.int64)
    xi, wq = gauss_points()
    pts = np.concatenate([xi, [1.0]])
    f = lambda *shape: np.zeros((n, *shape))
    s0, Sig, Psi = f(5, 3), f(5, 3, 6), f(5, 3, 6)
    mg, Ig = f(4), f(4, 3)
    mel, CS, CSS = f(), f(3, 6), f(6, 6)
    K, Kb, G = f(6, 6), f(6, 6), f(2, 2)
    l_, EA, mu = f(), f(), f()
    aF, aT, org, Crpy, axis, Q = f(3), f(3), f(3), f(3, 3), f(3), f(3, 3)
    hub_m, hub_J, pay_m, pay_d, pay_J = f(), f(3, 3), f(), f(3), f(3, 3)
    rigid = np.zeros(n, np.int64)
    rb_m, rb_c, rb_J = f(), f(3), f(3, 3)
    ks = np.full(n, k, np.int64)
    el0 = np.arange(n, dtype=np.int64) * k
    ext = np.zeros(n, np.int64)
    so = np.zeros(n, np.int64)
    locked = np.zeros(n, np.int64)
    ia = np.full(n, -1, np.int64)
    ie = np.zeros(n * k, np.int64)
    r = 0
    for i, link in enumerate(manip.links):
        b, jn = link.beam, link.joint
        l = b.length / k
        l_[i] = l
        if link.rigid:
            # k rigid slots of length l: no mass of their own, no stiffness, no coordinates;
            # the body in rb_* (docs/spatial.md §5, "Rigid links")
            s0[i], Sig[i], Psi[i] = shape_tables(l, False, pts)
            rigid[i] = 1
            rb_m[i], rb_c[i], rb_J[i] = b.mass, b.com, b.inertia_matrix
        else:
            ext[i] = b.EA is not None
            so[i] = ext[i] and strain == "second-order"
            EA[i] = b.EA or 0.0
            mu[i] = b.damping
            s0[i], Sig[i], Psi[i] = shape_tables(l, b.EA is not None, pts)
            mg[i] = wq * b.rhoA * l
            Ig[i] = np.outer(wq * l, [b.rhoJ, b.rhoIy, b.rhoIz])
            # the kernel's outboard step assumes S_O = [[D, 0], [0, J_L]]: check the tables' pattern
            D = np.diag([1.0 if b.EA is not None else 0.0, 1.0, 1.0])
            assert np.array_equal(Sig[i, 4], np.hstack([D, np.zeros((3, 3))]))
            assert np.array_equal(Psi[i, 4], np.hstack([np.zeros((3, 3)), np.eye(3)]))
            # ... and its Gauss-body step one entry per column of Σ_g, Ψ_g (pattern_ok), and the
            # linear element's step the sparsity of build.stiffness
            assert pattern_ok(Sig[i], Psi[i], s0[i])
            mel[i] = mg[i].sum()
            CS[i] = np.einsum("g,gij->ij", mg[i], Sig[i, :4])
            CSS[i] = np.einsum("g,gki,gkj->ij", mg[i], Sig[i, :4], Sig[i, :4])
            K[i] = stiffness(b, l)
            assert not np.any(K[i][~STIFFNESS_PATTERN])
            Kb[i] = K[i]
            Kb[i, 0, 0] = 0.0
            G[i] = g_matrix(l)
        a = np.array(jn.axis)
        Qi = rx(link.roll)  # a rigid link: no roll
        Q[i] = Qi
        Crpy[i] = rpy_matrix(jn.origin_rpy)
        axis[i] = a
        aF[i] = Qi.T @ a
        aT[i] = Crpy[i] @ a
        org[i] = jn.origin_xyz
        hub_m[i] = link.hub_mass
        hub_J[i] = Qi.T @ link.hub_inertia @ Qi
        pay_m[i] = link.payload_mass
        pay_d[i] = Qi.T @ link.payload_offset
        pay_J[i] = Qi.T @ link.payload_inertia @ Qi
        locked[i] = jn.locked
        if not jn.locked:
            ia[i] = r
            r += 1
        elif motion[i]:
            raise InputError(f"model.links[{i}].joint.locked", True, "a locked joint takes no drive")
        ne = 0 if link.rigid else 6 if b.EA is not None else 5
        for j in range(k):
            ie[i * k + j] = r
            r += ne
    return Model(
        n=n,
        nel=n * k,
        ndof=r,
        grav=np.array(manip.gravity, float),
        Rbase=rpy_matrix(manip.base_rpy),
        pbase=np.array(manip.base_xyz, float),
        k=ks,
        el0=el0,
        ext=ext,
        so=so,
        locked=locked,
        motion=motion,
        ia=ia,
        ie=ie,
        aF=aF,
        aT=aT,
        org=org,
        Crpy=Crpy,
        axis=axis,
        Q=Q,
        hub_m=hub_m,
        hub_J=hub_J,
        pay_m=pay_m,
        pay_d=pay_d,
        pay_J=pay_J,
        l=l_,
        K=K,
        Kb=Kb,
        EA=EA,
        mu=mu,
        G=G,
        s0=s0,
        Sig=Sig,
        Psi=Psi,
        mg=mg,
        Ig=Ig,
        mel=mel,
        CS=CS,
        CSS=CSS,
        rigid=rigid,
        rb_m=rb_m,
        rb_c=rb_c,
        rb_J=rb_J,
        par=np.array(manip.parents, np.int64),
    )


def make_work(md: Model) -> Work:
    nel, n = md.nel, md.n
    z = np.zeros
    return Work(
        Rw=z((nel, 3, 3)),
        pw=z((nel, 3)),
        vl=z((nel, 3)),
        wl=z((nel, 3)),
        E=z((nel, 3, 3)),
        JO=z((nel, 3, 3)),
        jdO=z((nel, 3)),
        sO=z((nel, 3)),
        e=z((nel, 6)),
        ed=z((nel, 6)),
        RT=z((n + 1, 3, 3)),
        pT=z((n + 1, 3)),
        vT=z((n + 1, 3)),
        wT=z((n + 1, 3)),
        C=z((n, 3, 3)),
        Lc=z((nel, 6, 6)),
        Y=z((nel, 6, 7)),
        zO=z((nel, 6)),
        Pc=z((nel, 6, 7)),
        Ptip=z((n, 6, 7)),
        PF=z((n, 6, 7)),
        zJ=z((n, 6)),
        acc=z((n, 3)),
        slope=z(n),
        wdF=z((n, 3)),
        Pacc=z((n + 1, 6, 7)),
        nacc=np.zeros(n + 1, np.int64),
        Atip=z((n + 1, 6)),
        M12=z((12, 12)),
        r12=z(12),
        E3=z((3, 3)),
        J3=z((3, 3)),
        jd3=z(3),
        Iw=z((3, 3)),
        IJ=z((3, 3)),
        N3=z((3, 3)),
        Cs=z((3, 3)),
        rho=z(6),
        P=z((6, 6)),
        c=z(6),
        KT=z((6, 6)),
        D6=z((6, 6)),
        f6=z(6),
        eh=z(6),
        edh=z(6),
        fx=z(6),
        Ps=z(6),
        A6=z(6),
        A6b=z(6),
        Rk=z((3, 3)),
        Tk=z((3, 3)),
        Uk=z((3, 3)),
        pk=z(3),
        vk=z(3),
        wk=z(3),
    )
