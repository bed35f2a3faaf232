"""The discretised arm: coordinate layout, element types, rigid bodies, forward kinematics.

Minimal coordinates, link by link: q = [α_1, e_{1,1}, …, e_{1,k}, α_2, e_{2,1}, …] with α_i
the joint angle and e_{i,j} the elastic coordinates of element j of link i.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from . import _validate
from .case import Case
from .element import ElementType, element_terms, element_type, outboard_maps, rot, strain_energy
from .errors import InputError

__all__ = ["Kinematics", "Structure", "build_structure"]


@dataclass
class LinkLayout:
    et: ElementType
    k: int
    i_alpha: int  # index of α in q
    e_slice: slice  # elastic coordinates of the link in q (k·ne entries)
    M_hub: np.ndarray  # diag(m, m, J) of the hub
    M_pay: np.ndarray  # diag(m, m, J) of the payload
    m_hub: float
    m_pay: float
    length: float
    rigid: bool = False  # a rigid link: no elastic coordinates, ``et`` None
    body: tuple = (0.0, 0.0, 0.0, 0.0)  # rigid link: mass, centre of mass (x, y), inertia about it
    pay_offset: tuple = (0.0, 0.0)  # centre of mass of the payload in the tip frame

    @property
    def ne(self) -> int:
        """Elastic coordinates per element (0 for a rigid link)."""
        return 0 if self.rigid else self.et.ne

    @property
    def mass(self) -> float:
        """Mass of the link (beam or body), hub and payload."""
        own = self.body[0] if self.rigid else self.et.m * self.k
        return own + self.m_hub + self.m_pay


@dataclass
class Structure:
    """Everything about the discretised case that does not change during a run."""

    case: Case
    k: int
    links: list
    n_dof: int
    gravity: np.ndarray
    motion: np.ndarray  # (n,) bool: joint is motion-driven
    n_elements: int

    @property
    def n_links(self) -> int:
        return len(self.links)

    @property
    def flexible_only(self) -> bool:
        """No rigid link and no offset payload (what the numpy reference sweeps model)."""
        return self.case.model.flexible_only

    def require_flexible(self, what: str) -> None:
        """Refuse a rigid link or an offset payload for ``what`` (one line naming the field)."""
        from .model import require_flexible

        require_flexible(self.case.model, what)

    @property
    def alpha_index(self) -> np.ndarray:
        return np.array([lk.i_alpha for lk in self.links])

    def coordinate_names(self) -> list[str]:
        names = []
        for i, lk in enumerate(self.links):
            names.append(f"joint {i + 1} angle")
            if lk.rigid:
                continue
            comps = ("u", "v", "phi") if lk.et.ne == 3 else ("v", "phi")
            for j in range(lk.k):
                names += [f"link {i + 1}, element {j + 1}, {c}" for c in comps]
        return names


STRAINS = ("linear", "second-order")


def build_structure(case: Case, elements_per_link, strain: str = "linear") -> Structure:
    """Discretise ``case`` with k elements per link (k ≥ 1, integer); ``strain`` is the
    element's axial strain measure (see :func:`dttmm.element.elastic_forces`)."""
    if strain not in STRAINS:
        raise InputError("strain", strain, f"unknown (one of: {', '.join(STRAINS)})")
    k = _validate.elements_per_link(elements_per_link)
    links, off = [], 0
    for link in case.model.links:
        b = link.beam
        if link.rigid:
            links.append(
                LinkLayout(
                    et=None,
                    k=k,
                    i_alpha=off,
                    e_slice=slice(off + 1, off + 1),
                    M_hub=np.diag([link.hub_mass, link.hub_mass, link.hub_inertia]),
                    M_pay=np.diag([link.payload_mass, link.payload_mass, link.payload_inertia]),
                    m_hub=link.hub_mass,
                    m_pay=link.payload_mass,
                    length=b.length,
                    rigid=True,
                    body=(b.mass, float(b.com[0]), float(b.com[1]), b.inertia),
                    pay_offset=tuple(float(x) for x in link.payload_offset),
                )
            )
            off += 1
            continue
        et = element_type(b.length / k, b.EI, b.rhoA, b.EA, b.damping, strain)
        links.append(
            LinkLayout(
                et=et,
                k=k,
                i_alpha=off,
                e_slice=slice(off + 1, off + 1 + k * et.ne),
                M_hub=np.diag([link.hub_mass, link.hub_mass, link.hub_inertia]),
                M_pay=np.diag([link.payload_mass, link.payload_mass, link.payload_inertia]),
                m_hub=link.hub_mass,
                m_pay=link.payload_mass,
                length=b.length,
                pay_offset=tuple(float(x) for x in link.payload_offset),
            )
        )
        off += 1 + k * et.ne
    motion = np.array([d.kind == "motion" for d in case.scenario.drives])
    return Structure(
        case=case,
        k=k,
        links=links,
        n_dof=off,
        gravity=np.asarray(case.model.gravity, float),
        motion=motion,
        n_elements=k * len(links),
    )


@dataclass
class LinkKin:
    """Kinematics and element terms of one link's elements at one (q, q̇)."""

    theta: np.ndarray  # (k,) frame angles
    thetad: np.ndarray
    r: np.ndarray  # (k, 2) inboard node positions
    rd: np.ndarray
    e: np.ndarray  # (k, ne)
    ed: np.ndarray
    R: np.ndarray  # (k, 2, 2)
    B_a: np.ndarray
    B_e: np.ndarray
    gbar: np.ndarray
    M_aa: np.ndarray
    M_ae: np.ndarray
    hbar_a: np.ndarray
    hbar_e: np.ndarray
    tip: np.ndarray  # (2,) tip position
    tip_theta: float
    tip_v: np.ndarray  # (3,) tip velocity (ẋ, ẏ, θ̇)


@dataclass
class Kinematics:
    links: list


def kinematics(st: Structure, q: np.ndarray, qd: np.ndarray, with_terms: bool = True) -> Kinematics:
    """Forward kinematics from the minimal coordinates, link by link (vectorised over elements).

    Positions: r_O = r_I + A(θ) s_O(e), θ_O = θ + φ; across joint i: θ⁺ = θ⁻ + α_i.
    Velocities: v_O = B_a v_I + B_e ė; across joint i: θ̇⁺ = θ̇⁻ + α̇_i.
    """
    st.require_flexible("the numpy reference kinematics (dttmm.structure; the kernel runs them)")
    g = st.gravity
    out = []
    p = np.zeros(2)
    th0, pv, thd0 = 0.0, np.zeros(2), 0.0
    for lk in st.links:
        et, k = lk.et, lk.k
        e = q[lk.e_slice].reshape(k, et.ne)
        ed = qd[lk.e_slice].reshape(k, et.ne)
        th_root = th0 + q[lk.i_alpha]
        thd_root = thd0 + qd[lk.i_alpha]
        phi, phid = e[:, et.iphi], ed[:, et.iphi]
        theta = th_root + np.concatenate(([0.0], np.cumsum(phi[:-1])))
        thetad = thd_root + np.concatenate(([0.0], np.cumsum(phid[:-1])))
        R = rot(theta)
        sO = et.sO0 + e @ et.SO.T
        rso = np.einsum("kij,kj->ki", R, sO)
        r = p + np.concatenate((np.zeros((1, 2)), np.cumsum(rso[:-1], axis=0)))
        # ṙ_O − ṙ_I = θ̇ E A s_O + A S_O ė
        dv = thetad[:, None] * (rso @ np.array([[0.0, 1.0], [-1.0, 0.0]])) + np.einsum(
            "kij,kj->ki", R, ed @ et.SO.T
        )
        rd = pv + np.concatenate((np.zeros((1, 2)), np.cumsum(dv[:-1], axis=0)))
        tip = r[-1] + rso[-1]
        tip_theta = theta[-1] + phi[-1]
        tip_v = np.array([*(rd[-1] + dv[-1]), thetad[-1] + phid[-1]])
        if with_terms:
            M_aa, M_ae, hbar_a, hbar_e, _ = element_terms(et, theta, thetad, e, ed, g)
            B_a, B_e, gbar, _ = outboard_maps(et, R, thetad, e, ed)
        else:
            M_aa = M_ae = hbar_a = hbar_e = B_a = B_e = gbar = None
        out.append(
            LinkKin(
                theta,
                thetad,
                r,
                rd,
                e,
                ed,
                R,
                B_a,
                B_e,
                gbar,
                M_aa,
                M_ae,
                hbar_a,
                hbar_e,
                tip,
                tip_theta,
                tip_v,
            )
        )
        p, th0, pv, thd0 = tip, tip_theta, tip_v[:2], tip_v[2]
    return Kinematics(out)


def energy(st: Structure, kin: Kinematics) -> float:
    """Kinetic + elastic + gravitational potential energy (J) of the discretised arm."""
    g = st.gravity
    total = 0.0
    for lk, lkn in zip(st.links, kin.links):
        et = lk.et
        # element generalised velocities p' = (ṙ_I, θ̇, ė); T = ½ p'ᵀ M p'
        pd = np.concatenate([lkn.rd, lkn.thetad[:, None]], axis=1)
        T = 0.5 * (
            np.einsum("ki,kij,kj->", pd, lkn.M_aa, pd)
            + 2 * np.einsum("ki,kij,kj->", pd, lkn.M_ae, lkn.ed)
            + np.einsum("ki,ij,kj->", lkn.ed, et.C_SS, lkn.ed)
        )
        V = strain_energy(et, lkn.e)
        ms = et.c_s0 + lkn.e @ et.C_S.T
        com = et.m * lkn.r + np.einsum("kij,kj->ki", lkn.R, ms)  # ∫ r dm
        V -= float(np.sum(com @ g))
        # hub at the root, payload at the tip
        v_root = np.array([*lkn.rd[0], lkn.thetad[0]])
        T += 0.5 * v_root @ lk.M_hub @ v_root + 0.5 * lkn.tip_v @ lk.M_pay @ lkn.tip_v
        V -= lk.m_hub * (lkn.r[0] @ g) + lk.m_pay * (lkn.tip @ g)
        total += T + V
    return float(total)
