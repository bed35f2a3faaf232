"""The common output of every method."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

__all__ = ["Result", "STATUSES", "tip_deflection", "make_result"]

#: Verdicts a run can carry. Only "ok" means the numbers can be trusted as computed:
#: "unconverged" — the step equations were not solved to tolerance (a fixed sweep count or an
#: exhausted iteration limit); "ill-conditioned" — the final system lost too many digits;
#: "failed" — the run stopped early (the result is the partial record up to the failure).
STATUSES = ("ok", "unconverged", "ill-conditioned", "failed")


def tip_deflection(link_root: np.ndarray, root_angle: np.ndarray, link_tip: np.ndarray) -> np.ndarray:
    """Transverse tip deflection in the clamped-root frame.

    Component of (tip − root) normal to the link's root cross-section direction:
    v = −sin θ_r (x_t − x_r) + cos θ_r (y_t − y_r).

    Shapes: link_root, link_tip (..., 2); root_angle (...) in rad. Returns (...) in m.
    """
    d = np.asarray(link_tip) - np.asarray(link_root)
    th = np.asarray(root_angle)
    return -np.sin(th) * d[..., 0] + np.cos(th) * d[..., 1]


@dataclass(frozen=True)
class Result:
    """Time histories on the output grid (rows are output times; SI units, radians).

    Attributes
    ----------
    t : (nt,) s
    joint_angle, joint_rate, joint_torque : (nt, n) rad, rad/s, N·m
        joint angle = root cross-section angle of the outboard link minus the tip
        cross-section angle of the inboard link (joint 1: minus the ground x axis).
    link_root, link_tip : (nt, n, 2) m
    tip_deflection : (nt, n) m, see :func:`tip_deflection`
    end_effector : (nt, 2) m, tip of the last link
    cut_loads : (nc, ncuts, 3) or None
        (M, Qx, Qy) transmitted across every cut (N·m, N), the load the inboard part exerts
        on the outboard part, at the times ``cut_load_t`` (nc,). Cuts per link: the root of
        every element and the link tip (k + 1), base link first.
    energy : (nt,) J or None
        Kinetic + elastic + gravitational potential energy.
    wall_time : s, the solve only (no model build)
    n_steps : number of integration steps taken
    meta : dict with at least method, elements_per_link, h, integrator, success, status, versions
    status : one of :data:`STATUSES`; ``success`` is True only for "ok"
    warnings : tuple of str, human-readable reasons for a status other than "ok" (and other
        caveats worth reading)
    link_shapes : (nt, n, p, 2) m or None ((nt, n, p, 3) in a spatial arm's SpatialResult)
        The deflected centre line of every link at every output time: the positions of p
        material points per link at the reference arc lengths x_m = L·(m − 1)/(p − 1),
        m = 1..p (so ``link_shapes[:, i, 0]`` is the link's root and ``link_shapes[:, i, -1]``
        its tip). Asked for with the method option ``shape_points=p`` (p ≥ 2; default 0, none
        recorded). DT-TMM and the global solver evaluate their element shape functions,
        Exudyn interpolates its node positions and slopes (cubic Hermite), the MuJoCo chain
        joins its pieces by straight lines, the rigid baseline draws straight links; see
        :mod:`dttmm.shapes`.
    """

    t: np.ndarray
    joint_angle: np.ndarray
    joint_rate: np.ndarray
    joint_torque: np.ndarray
    link_root: np.ndarray
    link_tip: np.ndarray
    tip_deflection: np.ndarray
    end_effector: np.ndarray
    wall_time: float
    n_steps: int
    meta: dict = field(default_factory=dict)
    cut_loads: np.ndarray | None = None
    cut_load_t: np.ndarray | None = None
    energy: np.ndarray | None = None
    status: str = "ok"
    warnings: tuple = ()
    link_shapes: np.ndarray | None = None

    def __post_init__(self):
        if self.status not in STATUSES:
            raise ValueError(f"Result.status: {self.status!r} is not one of {STATUSES}")
        object.__setattr__(self, "warnings", tuple(str(w) for w in self.warnings))
        self.meta["status"] = self.status
        self.meta["success"] = self.status == "ok"
        if self.warnings:
            self.meta["warnings"] = list(self.warnings)

    @property
    def success(self) -> bool:
        """True only when ``status == "ok"``."""
        return self.status == "ok"

    @property
    def n_joints(self) -> int:
        return self.joint_angle.shape[1]

    def to_frame(self):
        """Tidy table: one row per output time, one column per scalar quantity.

        Columns: t, joint_angle_i, joint_rate_i, joint_torque_i, tip_deflection_i,
        link_root_x_i, link_root_y_i, link_tip_x_i, link_tip_y_i (i = 1..n), end_effector_x,
        end_effector_y, energy (if computed), and with link shapes link_shape_x_i_m,
        link_shape_y_i_m (link i = 1..n, point m = 1..p). ``meta`` goes to ``DataFrame.attrs``.
        """
        import pandas as pd

        cols = {"t": self.t}
        for i in range(self.n_joints):
            j = i + 1
            cols[f"joint_angle_{j}"] = self.joint_angle[:, i]
            cols[f"joint_rate_{j}"] = self.joint_rate[:, i]
            cols[f"joint_torque_{j}"] = self.joint_torque[:, i]
            cols[f"tip_deflection_{j}"] = self.tip_deflection[:, i]
            for part, arr in (("link_root", self.link_root), ("link_tip", self.link_tip)):
                cols[f"{part}_x_{j}"] = arr[:, i, 0]
                cols[f"{part}_y_{j}"] = arr[:, i, 1]
        cols["end_effector_x"] = self.end_effector[:, 0]
        cols["end_effector_y"] = self.end_effector[:, 1]
        if self.energy is not None:
            cols["energy"] = self.energy
        if self.link_shapes is not None:
            _, n, p, _ = self.link_shapes.shape
            for i in range(n):
                for m in range(p):
                    cols[f"link_shape_x_{i + 1}_{m + 1}"] = self.link_shapes[:, i, m, 0]
                    cols[f"link_shape_y_{i + 1}_{m + 1}"] = self.link_shapes[:, i, m, 1]
        df = pd.DataFrame(cols)
        df.attrs.update(
            {k: v for k, v in self.meta.items() if isinstance(v, (str, int, float, bool, type(None)))}
        )
        df.attrs["wall_time"] = self.wall_time
        df.attrs["n_steps"] = self.n_steps
        df.attrs["status"] = self.status
        df.attrs["warnings"] = "\n".join(self.warnings)
        return df

    @classmethod
    def from_frame(cls, df, meta: dict | None = None) -> Result:
        """Rebuild a Result (without cut loads) from :meth:`to_frame`'s table."""
        n = sum(1 for c in df.columns if c.startswith("joint_angle_"))
        get = lambda p: np.column_stack([df[f"{p}_{j}"].to_numpy() for j in range(1, n + 1)])
        xy = lambda p: np.stack([get(f"{p}_x"), get(f"{p}_y")], axis=-1)
        m = dict(df.attrs)
        m.update(meta or {})
        status = m.pop("status", "ok" if m.get("success", True) else "failed")
        warns = m.pop("warnings", ())
        warns = tuple(w for w in warns.split("\n") if w) if isinstance(warns, str) else tuple(warns)
        shapes = None
        n_shape = sum(1 for c in df.columns if c.startswith("link_shape_x_"))
        if n_shape:
            p = n_shape // n
            shapes = np.stack(
                [
                    np.stack(
                        [
                            np.column_stack([df[f"link_shape_{c}_{j}_{m}"].to_numpy() for c in "xy"])
                            for m in range(1, p + 1)
                        ],
                        axis=1,
                    )
                    for j in range(1, n + 1)
                ],
                axis=1,
            )
        return cls(
            t=df["t"].to_numpy(),
            joint_angle=get("joint_angle"),
            joint_rate=get("joint_rate"),
            joint_torque=get("joint_torque"),
            link_root=xy("link_root"),
            link_tip=xy("link_tip"),
            tip_deflection=get("tip_deflection"),
            end_effector=df[["end_effector_x", "end_effector_y"]].to_numpy(),
            wall_time=float(m.pop("wall_time", np.nan)),
            n_steps=int(m.pop("n_steps", 0)),
            meta=m,
            energy=df["energy"].to_numpy() if "energy" in df else None,
            status=status,
            warnings=warns,
            link_shapes=shapes,
        )


def make_result(
    *,
    t,
    joint_angle,
    joint_rate,
    joint_torque,
    link_root,
    link_root_angle,
    link_tip,
    wall_time,
    n_steps,
    meta,
    cut_loads=None,
    cut_load_t=None,
    energy=None,
    status=None,
    warnings=(),
    link_shapes=None,
) -> Result:
    """Assemble a Result, deriving tip deflections and the end-effector from the link frames
    so every method uses the same definitions. ``link_root_angle`` (nt, n): absolute angle
    of each link's root cross-section (rad). ``status`` defaults to "ok", or "failed" when
    ``meta["success"]`` is False. ``link_shapes`` (nt, n, p, 2) m or None: see :class:`Result`."""
    if status is None:
        status = meta.get("status") or ("ok" if meta.get("success", True) is not False else "failed")
    link_root = np.asarray(link_root, float)
    link_tip = np.asarray(link_tip, float)
    return Result(
        t=np.asarray(t, float),
        joint_angle=np.asarray(joint_angle, float),
        joint_rate=np.asarray(joint_rate, float),
        joint_torque=np.asarray(joint_torque, float),
        link_root=link_root,
        link_tip=link_tip,
        tip_deflection=tip_deflection(link_root, link_root_angle, link_tip),
        end_effector=link_tip[:, -1, :].copy(),
        wall_time=float(wall_time),
        n_steps=int(n_steps),
        meta=dict(meta),
        cut_loads=cut_loads,
        cut_load_t=cut_load_t,
        energy=energy,
        status=status,
        warnings=tuple(warnings),
        link_shapes=None if link_shapes is None else np.asarray(link_shapes, float),
    )
