"""The Result of a spatial run: :class:`dttmm.Result` with 3-D fields."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..result import Result

__all__ = ["SpatialResult"]


@dataclass(frozen=True)
class SpatialResult(Result):
    """A :class:`dttmm.Result` of a spatial arm (docs/spatial.md §4), n links, m unlocked joints:

    joint_angle, joint_rate, joint_torque (nt, m); link_root, link_tip (nt, n, 3) m;
    end_effector (nt, 3); tip_deflection (nt, n, 2): components of tip − root along the link
    frame's y and z axes (m); twist (nt, n): the x component of log(R_rootᵀ R_tip) (rad);
    cut_loads (nc, n_cuts, 6): force and moment (N, N·m; world components, moment about the
    cut's point) that the inboard part exerts on the outboard part, at every element root and
    every link tip (k + 1 cuts per link, base link first); link_rotation, tip_rotation
    (nt, n, 3, 3): the link frame at the root and the tip frame; link_shapes (nt, n, p, 3) m or
    None: p material points per link from root to tip (``shape_points=p``, as
    :attr:`dttmm.Result.link_shapes`).
    """

    twist: np.ndarray | None = None
    link_rotation: np.ndarray | None = None
    tip_rotation: np.ndarray | None = None
    #: with loop closures (docs/spatial.md "Trees and closed loops"), on the output grid:
    #: (nt, n_closures, 6) force (N) and moment (N·m, about the closure point), world
    #: components, that `to` exerts on `link`; the position gap |p_a − p_b| (m) and the angle
    #: gap (rad; 0 for a spherical closure), (nt, n_closures) each
    closure_loads: np.ndarray | None = None
    closure_residual: np.ndarray | None = None
    closure_angle_residual: np.ndarray | None = None

    @property
    def n_links(self) -> int:
        return self.link_root.shape[1]

    def to_frame(self):
        """Tidy table: one row per output time, one column per scalar quantity.

        Columns: t; joint_angle_j, joint_rate_j, joint_torque_j (unlocked joint j = 1..m);
        per link i = 1..n: link_root_{x,y,z}_i, link_tip_{x,y,z}_i, tip_deflection_{y,z}_i,
        twist_i and, when recorded, link_rotation_{rc}_i and tip_rotation_{rc}_i (row r,
        column c of the 3×3 matrix, 1-based); end_effector_{x,y,z}; energy (if computed); with
        cut loads recorded on the output grid, per cut c = 1..n_cuts (k + 1 per link, base link
        first) cut_force_{x,y,z}_c and cut_moment_{x,y,z}_c (world components); with link shapes,
        per link i and point m = 1..p link_shape_{x,y,z}_i_m; with loop closures, per closure
        j = 1..n_closures closure_force_{x,y,z}_j and closure_moment_{x,y,z}_j (world, what `to`
        exerts on `link`), closure_residual_j and closure_angle_residual_j. ``meta`` goes to
        ``DataFrame.attrs``.
        """
        import pandas as pd

        cols = {"t": self.t}
        for j in range(self.n_joints):
            for name in ("joint_angle", "joint_rate", "joint_torque"):
                cols[f"{name}_{j + 1}"] = getattr(self, name)[:, j]
        for i in range(self.n_links):
            for part in ("link_root", "link_tip"):
                for c, ax in enumerate("xyz"):
                    cols[f"{part}_{ax}_{i + 1}"] = getattr(self, part)[:, i, c]
            for c, ax in enumerate("yz"):
                cols[f"tip_deflection_{ax}_{i + 1}"] = self.tip_deflection[:, i, c]
            if self.twist is not None:
                cols[f"twist_{i + 1}"] = self.twist[:, i]
            for part in ("link_rotation", "tip_rotation"):
                rot = getattr(self, part)
                if rot is not None:
                    for r in range(3):
                        for c in range(3):
                            cols[f"{part}_{r + 1}{c + 1}_{i + 1}"] = rot[:, i, r, c]
        for c, ax in enumerate("xyz"):
            cols[f"end_effector_{ax}"] = self.end_effector[:, c]
        if self.energy is not None:
            cols["energy"] = self.energy
        if self.cut_loads is not None:
            if self.cut_load_t is None or not np.array_equal(self.cut_load_t, self.t):
                raise ValueError("SpatialResult.to_frame: the cut loads are not on the output grid")
            for cut in range(self.cut_loads.shape[1]):
                for part, off in (("force", 0), ("moment", 3)):
                    for c, ax in enumerate("xyz"):
                        cols[f"cut_{part}_{ax}_{cut + 1}"] = self.cut_loads[:, cut, off + c]
        if self.link_shapes is not None:
            _, n, p, _ = self.link_shapes.shape
            for i in range(n):
                for m in range(p):
                    for c, ax in enumerate("xyz"):
                        cols[f"link_shape_{ax}_{i + 1}_{m + 1}"] = self.link_shapes[:, i, m, c]
        if self.closure_loads is not None:
            for j in range(self.closure_loads.shape[1]):
                for part, off in (("force", 0), ("moment", 3)):
                    for c, ax in enumerate("xyz"):
                        cols[f"closure_{part}_{ax}_{j + 1}"] = self.closure_loads[:, j, off + c]
                for name in ("closure_residual", "closure_angle_residual"):
                    values = getattr(self, name)
                    if values is not None:
                        cols[f"{name}_{j + 1}"] = values[:, j]
        df = pd.DataFrame(cols)
        df.attrs.update(
            {k: v for k, v in self.meta.items() if isinstance(v, (str, int, float, bool, type(None)))}
        )
        df.attrs.update(kind="spatial", wall_time=self.wall_time, n_steps=self.n_steps, status=self.status)
        df.attrs["warnings"] = "\n".join(self.warnings)
        return df

    @classmethod
    def from_frame(cls, df, meta: dict | None = None) -> SpatialResult:
        """Rebuild a SpatialResult from :meth:`to_frame`'s table."""
        m_j = sum(1 for c in df.columns if c.startswith("joint_angle_"))
        n = sum(1 for c in df.columns if c.startswith("tip_deflection_y_"))
        col = lambda name: df[name].to_numpy()
        nt = len(df)
        # an arm of locked joints only has no joint columns: (nt, 0)
        per_joint = lambda p: np.column_stack(
            [np.zeros((nt, 0)), *(col(f"{p}_{j}") for j in range(1, m_j + 1))]
        ).reshape(nt, m_j)
        per_link = lambda p, axes: np.stack(
            [np.column_stack([col(f"{p}_{a}_{i}") for a in axes]) for i in range(1, n + 1)], axis=1
        )

        def rotation(p):
            if f"{p}_11_1" not in df:
                return None
            return np.stack(
                [
                    np.stack(
                        [np.column_stack([col(f"{p}_{r}{c}_{i}") for c in (1, 2, 3)]) for r in (1, 2, 3)],
                        axis=1,
                    )
                    for i in range(1, n + 1)
                ],
                axis=1,
            )

        n_cuts = sum(1 for c in df.columns if c.startswith("cut_force_x_"))
        loads = None
        if n_cuts:
            loads = np.stack(
                [
                    np.column_stack(
                        [col(f"cut_{part}_{ax}_{c}") for part in ("force", "moment") for ax in "xyz"]
                    )
                    for c in range(1, n_cuts + 1)
                ],
                axis=1,
            )
        n_shape = sum(1 for c in df.columns if c.startswith("link_shape_x_"))
        link_shapes = None
        if n_shape:
            p = n_shape // n
            link_shapes = np.stack(
                [
                    np.stack(
                        [
                            np.column_stack([col(f"link_shape_{a}_{i}_{m}") for a in "xyz"])
                            for m in range(1, p + 1)
                        ],
                        axis=1,
                    )
                    for i in range(1, n + 1)
                ],
                axis=1,
            )
        n_cl = sum(1 for c in df.columns if c.startswith("closure_force_x_"))
        closure = {}
        if n_cl:
            closure["closure_loads"] = np.stack(
                [
                    np.column_stack(
                        [col(f"closure_{part}_{ax}_{j}") for part in ("force", "moment") for ax in "xyz"]
                    )
                    for j in range(1, n_cl + 1)
                ],
                axis=1,
            )
            for name in ("closure_residual", "closure_angle_residual"):
                if f"{name}_1" in df:
                    closure[name] = np.column_stack([col(f"{name}_{j}") for j in range(1, n_cl + 1)])
        m = dict(df.attrs)
        m.update(meta or {})
        m.pop("kind", None)
        status = m.pop("status", "ok" if m.get("success", True) else "failed")
        warns = m.pop("warnings", ())
        warns = tuple(w for w in warns.split("\n") if w) if isinstance(warns, str) else tuple(warns)
        return cls(
            t=col("t"),
            joint_angle=per_joint("joint_angle"),
            joint_rate=per_joint("joint_rate"),
            joint_torque=per_joint("joint_torque"),
            link_root=per_link("link_root", "xyz"),
            link_tip=per_link("link_tip", "xyz"),
            tip_deflection=per_link("tip_deflection", "yz"),
            end_effector=df[["end_effector_x", "end_effector_y", "end_effector_z"]].to_numpy(),
            wall_time=float(m.pop("wall_time", np.nan)),
            n_steps=int(m.pop("n_steps", 0)),
            meta=m,
            energy=col("energy") if "energy" in df else None,
            status=status,
            warnings=warns,
            twist=np.column_stack([col(f"twist_{i}") for i in range(1, n + 1)]) if "twist_1" in df else None,
            link_rotation=rotation("link_rotation"),
            tip_rotation=rotation("tip_rotation"),
            cut_loads=loads,
            cut_load_t=col("t").copy() if loads is not None else None,
            link_shapes=link_shapes,
            **closure,
        )
