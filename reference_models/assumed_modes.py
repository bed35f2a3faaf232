"""The assumed modes method (AMM): every link's deflection a sum of N assumed mode shapes.

The model (docs/assumed_modes.md has the derivation and the measured facts):

* **Kinematics.** Link i has a frame at its root cross-section (the clamped-root frame of the
  suite). A material point at arc length x sits at s(x) = (x + u(x), w(x)) in that frame, with
  w = Σ_j φ_ij(x) δ_ij and, in the consistent variant, the second-order foreshortening
  u = −½ ∫₀ˣ w'² dx. The next link's root frame is the tip frame (tip position, tip
  cross-section angle) turned by the joint angle, so joint angle = outboard root section angle −
  inboard tip section angle, and the tip deflection normal to the root section is φ_L·δ.
* **Modes.** Each link's own beam eigenproblem, clamped at the root (:mod:`._amm_shapes`). The
  default ``boundary="clamped-mass"`` loads the tip with the rigid mass and rotary inertia of
  everything outboard, arm straight (outboard joints at 0), static moment left out — De Luca &
  Siciliano's choice, kept as the default because it reproduces their published modal data.
  It does not converge faster on the shipped cases: on ``three_link`` both bases reach the same
  end-effector error (0.23–0.25 mm) by N = 3–4, and at N = 1 clamped-free is better (1.2 against
  2.0 mm). ``"clamped-free"``
  is offered for comparison. Any choice is a basis; it changes the truncation error, not the
  equations.
* **Equations.** Lagrange's equations of the whole arm in closed form per body, assembled
  recursively from the base (:mod:`._amm_numba`): M(q) q̈ + f(q, q̇) + Kδ + Dδ̇ = Bτ with
  q = (joint angles, modal amplitudes), hubs and payloads as rigid bodies, gravity, and
  stiffness-proportional (Kelvin–Voigt) damping D = μK.
* **Variants** (Padilla & von Flotow's names): ``"consistent"`` keeps the foreshortening to
  second order, which gives the geometric stiffening of every axial load — centrifugal, the
  axial acceleration of the link root, gravity along the link and the inertia of the outboard
  arm and payload pulling on the tip; ``"premature"`` keeps the centrifugal softening
  (θ̇² ∫ρA w²) without the stiffening; ``"ruthless"`` has neither (the link's own θ̇² δ² terms
  dropped, and the tip kept at its distance L from the root, so the outboard arm neither softens
  nor stiffens it). All three are Lagrangian (kinetic energy to second order in δ) and conserve
  energy. On torque-driven links with slow hubs the consistent variant's second-order terms in
  the hub equation are no better than the third-order terms it drops (see the doc).
* **Default: "consistent".** Rule: the default must stay bounded and within the tolerance
  on every benchmark problem it can model; only the consistent variant passes the
  spin-up benchmark problems (ω_s = 4, 6: premature diverges, ruthless is 5–10 % off). Where the links
  stay within a few percent of their length all variants agree; on the shipped ``single_link``
  at its nominal torque (deflections of 12–23 % of the length) no truncated variant is accurate
  and ruthless happens to be closest — see the doc's table.

Time integration: Newmark (β = ¼, γ = ½) or generalised-α (Arnold–Brüls form, ρ∞), the step
equations solved by a modified Newton iteration (exact M, K, D and law slopes; the velocity and
configuration derivatives of M and f left out) to a relative tolerance, compiled with numba.
Drives: torque laws, motion laws (the joint follows the law; its torque is an output), and the
closed-loop ``pd``/``pid`` laws with moment feedback through :func:`dttmm.control.pd_torque`
(the root moment of the hub balance, τ − J_hub ω̇), evaluated implicitly at the step end; user
laws (Python callables) are refused.
"""

from __future__ import annotations

import time
from collections import namedtuple

import numpy as np

from dttmm.control import CODE_USER, gains, time_tables
from dttmm.errors import InputError
from dttmm.model import require_flexible
from dttmm.plumbing import (
    choice,
    newmark_family,
    positive_integer,
    positive_number,
    simulation_failure,
    versions,
)
from dttmm.result import make_result
from dttmm.timegrid import step_schedule

from . import _amm_numba as _k
from ._amm_shapes import BOUNDARIES, LinkModes, link_modes, outboard_inertia

__all__ = [
    "BOUNDARIES",
    "DEFAULT_VARIANT",
    "INTEGRATORS",
    "VARIANTS",
    "link_frequencies",
    "modes",
    "simulate",
]

VARIANTS = ("consistent", "ruthless", "premature")
DEFAULT_VARIANT = "consistent"
#: integrator name -> its options and their defaults
INTEGRATORS = {
    "newmark": {"beta": 0.25, "gamma": 0.5, "tol": 1e-10, "max_iter": 50},
    "generalized-alpha": {"rho_inf": 0.9, "tol": 1e-10, "max_iter": 50},
}
MAX_MODES = 30
CODE_MOTION = 3

Pack = namedtuple(
    "Pack",
    "n N g L m s0 I0 c d M K D Hc A Gc phiL dphiL hub_m hub_J pay_m pay_J "
    "code kp kd ki gm limit jhub Wrow free Kfull Dfull",
)
Tables = namedtuple("Tables", "ff ref mot")


# ----------------------------------------------------------------------------- the model
def _link_shapes(case, N: int, boundary: str) -> list[LinkModes]:
    out = []
    for i, lk in enumerate(case.model.links):
        mo, jo = outboard_inertia(case.model, i) if boundary == "clamped-mass" else (0.0, 0.0)
        out.append(link_modes(lk.beam, N, mo, jo))
    return out


def _pack(case, N: int, variant: str, boundary: str) -> tuple[Pack, list[LinkModes]]:
    """The compiled model's data (arrays per link, stacked) and the link modes."""
    links = case.model.links
    n = len(links)
    nq = n + n * N
    sh = _link_shapes(case, N, boundary)
    cons = variant == "consistent"
    stack = lambda f: np.ascontiguousarray(np.array([f(s) for s in sh], float))
    M, K = stack(lambda s: s.M), stack(lambda s: s.K)
    mu = np.array([lk.beam.damping for lk in links])
    A = {"consistent": M - stack(lambda s: s.P), "premature": M, "ruthless": 0.0 * M}[variant]
    zero = np.zeros_like(M)
    g = gains(case)
    code = g.code.copy()
    for i, d in enumerate(case.scenario.drives):
        if d.kind == "motion":
            code[i] = CODE_MOTION
    W = np.zeros((n, nq))  # ω̇_i = W_i q̈: the root cross-section of link i
    for i in range(n):
        W[i, : i + 1] = 1.0
        for j in range(i):
            W[i, n + j * N : n + (j + 1) * N] = sh[j].dphi_L
    Kf, Df = np.zeros((nq, nq)), np.zeros((nq, nq))
    for i in range(n):
        b = slice(n + i * N, n + (i + 1) * N)
        Kf[b, b], Df[b, b] = K[i], mu[i] * K[i]
    free = np.array([i for i in range(nq) if i >= n or code[i] != CODE_MOTION], np.int64)
    arr = lambda v: np.ascontiguousarray(np.asarray(v, float))
    pack = Pack(
        n=n,
        N=N,
        g=arr(case.model.gravity),
        L=arr([lk.beam.length for lk in links]),
        m=arr([lk.beam.mass for lk in links]),
        s0=arr([lk.beam.rhoA * lk.beam.length**2 / 2 for lk in links]),
        I0=arr([lk.beam.rhoA * lk.beam.length**3 / 3 for lk in links]),
        c=stack(lambda s: s.c),
        d=stack(lambda s: s.d),
        M=M,
        K=K,
        D=arr(mu[:, None, None] * K),
        Hc=stack(lambda s: s.H) if cons else zero,
        A=arr(A),
        Gc=_tip_foreshortening(sh, links, variant),
        phiL=stack(lambda s: s.phi_L),
        dphiL=stack(lambda s: s.dphi_L),
        hub_m=arr([lk.hub_mass for lk in links]),
        hub_J=arr([lk.hub_inertia for lk in links]),
        pay_m=arr([lk.payload_mass for lk in links]),
        pay_J=arr([lk.payload_inertia for lk in links]),
        code=np.ascontiguousarray(code, np.int64),
        kp=arr(g.kp),
        kd=arr(g.kd),
        ki=arr(g.ki),
        gm=arr(g.moment_gain),
        limit=arr(g.limit),
        jhub=arr(g.j_hub),
        Wrow=W,
        free=free,
        Kfull=Kf,
        Dfull=Df,
    )
    return pack, sh


def _tip_foreshortening(sh, links, variant: str) -> np.ndarray:
    """G of the tip lever ℓ = (L − ½ δᵀGδ, φ_Lᵀδ) per link, (n, N, N).

    consistent: G_L = ∫φ'φ'ᵀ, the foreshortening of the beam (the outboard arm's axial loads
    stiffen the link); premature: 0 (the tip moves transversely: the outboard arm's centrifugal
    force softens it); ruthless: φ_Lφ_Lᵀ/L, the tip keeps its distance L from the root to second
    order, so the outboard arm's centrifugal potential does not depend on δ (neither term).
    """
    if variant == "consistent":
        return np.ascontiguousarray(np.array([s.G_L for s in sh]))
    if variant == "ruthless":
        return np.ascontiguousarray(
            np.array([np.outer(s.phi_L, s.phi_L) / lk.beam.length for s, lk in zip(sh, links)])
        )
    return np.zeros((len(sh), sh[0].M.shape[0], sh[0].M.shape[0]))


def _tables(case, times, left: bool) -> tuple:
    """(ff, ref, mot) of the drive laws at ``times``: torques / feedforward (nt, n),
    pd/pid references (nt, n, 2), motion laws (α, α̇, α̈) (nt, n, 3)."""
    ff, ref = time_tables(case, times, left)
    mot = np.zeros((len(times), len(case.scenario.drives), 3))
    for i, d in enumerate(case.scenario.drives):
        if d.kind == "motion":
            mot[:, i] = [d.motion(float(t), left) for t in times]
    return ff, ref, mot


def _step_tables(case, T) -> Tables:
    """Rows 2k: left limits at T[k]; 2k + 1: right limits at T[k]."""
    lft, rgt = _tables(case, T, True), _tables(case, T, False)
    out = []
    for a, b in zip(lft, rgt):
        x = np.empty((2 * a.shape[0], *a.shape[1:]))
        x[0::2], x[1::2] = a, b
        out.append(np.ascontiguousarray(x))
    return Tables(*out)


# ----------------------------------------------------------------------------- checks
def _check(case, N, h, variant, integrator, boundary, options):
    N = positive_integer("elements_per_link", N)
    if N > MAX_MODES:
        raise InputError("elements_per_link", N, f"modes per link must not exceed {MAX_MODES}")
    choice("variant", variant, VARIANTS)
    choice("boundary", boundary, BOUNDARIES)
    choice("integrator", integrator, tuple(INTEGRATORS))
    known = INTEGRATORS[integrator]
    for key in options:
        if key not in known:
            raise InputError(
                key, options[key], f"is not an option of integrator {integrator!r} ({', '.join(known)})"
            )
    opts = {**known, **options}
    opts["tol"] = positive_number("tol", opts["tol"])
    opts["max_iter"] = positive_integer("max_iter", opts["max_iter"])
    if integrator == "newmark":
        fam = newmark_family("newmark", beta=opts["beta"], gamma=opts["gamma"])
    else:
        fam = newmark_family("generalized-alpha", rho_inf=opts["rho_inf"])
    for i, d in enumerate(case.scenario.drives):
        if d.closed_loop and gains(case).code[i] == CODE_USER:
            raise InputError(
                f"scenario.drives[{i}].law",
                d.law.label,
                "a Python user law cannot run in the compiled assumed-modes loop (use a pd/pid law)",
            )
    return N, float(h), fam, opts


# ----------------------------------------------------------------------------- outputs
def _hermite(T, Q, V, Ar, Al, t, h):
    """Node states to times t: node values where t hits a node, else cubic Hermite on (q, q̇)
    and (q̇, q̈); accelerations linear between the one-sided node values."""
    k = np.clip(np.searchsorted(T, t, side="right") - 1, 0, max(T.size - 2, 0))
    if T.size == 1:
        z = np.zeros(t.size, int)
        return Q[z], V[z], Ar[z]
    d = (T[k + 1] - T[k])[:, None]
    s = (t[:, None] - T[k][:, None]) / d
    h00, h10, h01, h11 = (1 + 2 * s) * (1 - s) ** 2, s * (1 - s) ** 2, s * s * (3 - 2 * s), s * s * (s - 1)
    q = h00 * Q[k] + h10 * d * V[k] + h01 * Q[k + 1] + h11 * d * V[k + 1]
    v = h00 * V[k] + h10 * d * Ar[k] + h01 * V[k + 1] + h11 * d * Al[k + 1]
    a = (1 - s) * Ar[k] + s * Al[k + 1]
    j = np.clip(np.searchsorted(T, t - 1e-9 * h), 0, T.size - 1)
    hit = np.abs(T[j] - t) <= 1e-9 * h
    q[hit], v[hit], a[hit] = Q[j[hit]], V[j[hit]], Ar[j[hit]]
    return q, v, a


def _outputs(case, pack, t, q, v, a, z):
    """Joint torques (nt, n), link roots (nt, n, 2), root angles (nt, n), tips (nt, n, 2) and
    energy (nt,) at the output samples."""
    n, nt = pack.n, t.size
    tab = Tables(*_tables(case, t, False))
    tau, frames, energy = np.zeros((nt, n)), np.zeros((nt, n, 6)), np.zeros(nt)
    c = np.ascontiguousarray
    _k.outputs(pack, tab, c(q), c(v), c(a), c(z), tau, frames, energy)
    return tau, frames[..., 0:2], frames[..., 2], frames[..., 3:5], energy


# ----------------------------------------------------------------------------- public API
def link_frequencies(case, modes_per_link: int, boundary: str = "clamped-mass") -> np.ndarray:
    """Eigenfrequencies (n_links, N) in Hz of every link's own assumed-mode eigenproblem (root
    clamped; tip free or with the outboard inertia of the straight arm, static moment left
    out). With De Luca & Siciliano's arm these are the frequencies their paper quotes."""
    N = positive_integer("modes_per_link", modes_per_link)
    choice("boundary", boundary, BOUNDARIES)
    return np.array([s.freq for s in _link_shapes(case, N, boundary)])


def modes(
    case, modes_per_link: int, *, variant: str = DEFAULT_VARIANT, boundary: str = "clamped-mass", n=None
):
    """Natural frequencies (Hz) of the AMM arm linearised about its initial state at rest:
    motion-driven joints held, torque-driven joints free (rigid-body modes at 0 Hz).

    M is the arm's mass matrix there; the stiffness K_t = ∂f/∂q (modal stiffness, and gravity
    and, in the consistent variant, its geometric stiffness) by central differences.

    Returns
    -------
    (n or n_free,) array, Hz, ascending.
    """
    N = positive_integer("modes_per_link", modes_per_link)
    choice("variant", variant, VARIANTS)
    choice("boundary", boundary, BOUNDARIES)
    pack, _ = _pack(case, N, variant, boundary)
    nq = pack.n * (1 + N)
    q0 = np.zeros(nq)
    for i, d in enumerate(case.scenario.drives):
        q0[i] = d.motion(0.0)[0] if d.kind == "motion" else d.initial_angle
    Mq, fq, frames = np.zeros((nq, nq)), np.zeros(nq), np.zeros((pack.n, 6))
    zero = np.zeros(nq)

    def force(q):
        _k.assemble(q, zero, pack, Mq, fq, frames)
        return fq.copy()

    fr = pack.free
    K = np.zeros((fr.size, fr.size))
    for j, c in enumerate(fr):
        e = np.zeros(nq)
        e[c] = 1e-6
        K[:, j] = ((force(q0 + e) - force(q0 - e)) / 2e-6)[fr]
    _k.assemble(q0, zero, pack, Mq, fq, frames)
    import scipy.linalg

    lam = scipy.linalg.eigh(0.5 * (K + K.T), Mq[np.ix_(fr, fr)], eigvals_only=True)
    lam = np.where(np.abs(lam) <= 1e-9 * np.abs(lam).max(), 0.0, lam)
    f = np.sqrt(np.maximum(lam, 0.0)) / (2 * np.pi)
    return f if n is None else f[: positive_integer("n", n)]


def simulate(
    case,
    *,
    elements_per_link,
    h,
    variant: str = DEFAULT_VARIANT,
    integrator: str = "newmark",
    boundary: str = "clamped-mass",
    progress: bool = False,
    **options,
):
    """Simulate a case with the assumed modes method.

    Parameters
    ----------
    case : dttmm.Case
    elements_per_link : int
        N, the number of assumed modes per link (1 … 30), in the suite's common argument.
    h : float
        Step size (s).
    variant : ``"consistent"`` (default) | ``"ruthless"`` | ``"premature"``
        Geometric stiffening and centrifugal softening (see the module docstring).
    integrator : ``"newmark"`` | ``"generalized-alpha"``
    boundary : ``"clamped-mass"`` (default) | ``"clamped-free"``
        Tip condition of the link eigenproblems that give the mode shapes.
    progress : bool
        Accepted for the common call; the compiled loop prints nothing.
    **options
        newmark: beta (¼), gamma (½); generalized-alpha: rho_inf (0.9); both: tol (1e-10,
        relative correction of the step iteration), max_iter (50).

    Returns
    -------
    dttmm.Result on ``case.scenario.output_times``, ``energy`` (kinetic + elastic + gravity,
    J); no cut loads. ``wall_time`` covers the time loop only; ``meta["cpu_time_solve"]`` its
    CPU time; ``meta["link_frequencies"]`` the eigenfrequencies of the link shapes (Hz).

    Raises
    ------
    dttmm.InputError
        bad N, h, variant, boundary, integrator or option; a Python user law.
    dttmm.SimulationError
        non-finite state; ``partial`` holds the outputs up to the last good step.
    """
    N, h, fam, opts = _check(case, elements_per_link, h, variant, integrator, boundary, options)
    require_flexible(case.model, "assumed modes (flexible links, bodies on the beam axis)")
    scen = case.scenario
    T_end, restart = step_schedule(scen.duration, h, scen.breakpoints)
    T = np.concatenate([[0.0], T_end])
    pack, sh = _pack(case, N, variant, boundary)
    tab = _step_tables(case, T)
    n, nq = pack.n, pack.n * (1 + N)
    q0, v0 = np.zeros(nq), np.zeros(nq)
    for i, d in enumerate(scen.drives):
        if d.kind == "torque":
            q0[i], v0[i] = d.initial_angle, d.initial_rate
    ns = T.size
    Q, V, Ar, Al, Z = (np.zeros((ns, m)) for m in (nq, nq, nq, nq, n))
    t0, c0 = time.perf_counter(), time.process_time()
    with np.errstate(all="ignore"):
        status, last, iters, bad = _k.run(
            pack, tab, T, restart, q0, v0, fam.beta, fam.gamma, fam.alpha_m, fam.alpha_f,
            opts["tol"], opts["max_iter"], Q, V, Ar, Al, Z,
        )  # fmt: skip
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    meta = {
        "method": "assumed-modes",
        "elements_per_link": N,
        "modes_per_link": N,
        "h": h,
        "integrator": integrator,
        "variant": variant,
        "boundary": boundary,
        "versions": versions(),
        "cpu_time_solve": cpu,
        "iterations_mean": iters / max(last, 1),
        "link_frequencies": [s.freq.tolist() for s in sh],
        **{k: v for k, v in opts.items()},
    }
    warnings = []
    if bad:
        warnings.append(
            f"{bad} of {last} steps ended with the step iteration unconverged (tol {opts['tol']:g})"
        )
        meta["status"] = "unconverged"
    good = last + 1 if status == _k.OK else last + 1
    t_out = scen.output_times
    tg = t_out[t_out <= T[good - 1] + 1e-9 * h]

    def result(m):
        q, v, a = _hermite(T[:good], Q[:good], V[:good], Ar[:good], Al[:good], tg, h)
        z = _hermite(T[:good], Z[:good], Z[:good], Z[:good], Z[:good], tg, h)[0]
        tau, root, ang, tip, energy = _outputs(case, pack, tg, q, v, a, z)
        return make_result(
            t=tg,
            joint_angle=q[:, :n],
            joint_rate=v[:, :n],
            joint_torque=tau,
            link_root=root,
            link_root_angle=ang,
            link_tip=tip,
            wall_time=wall,
            n_steps=last,
            meta=m,
            energy=energy,
            warnings=warnings,
        )

    if status != _k.OK:
        comp = "state"
        raise simulation_failure(
            "non-finite state", t=float(T[last + 1]), step=last, component=comp, meta=meta, partial=result
        )
    return result(meta)
