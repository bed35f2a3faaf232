"""The report's "Motion" section: one animation per case of the report.

Two halves, like the rest of the report: :func:`motion_table` runs DT-TMM (and the rigid
baseline, for contrast) with link shapes on every case and keeps the frames as a tidy table
(``motion``: case, method, frame, t, link, point, x, y), stored with the study tables;
:func:`section` draws them from that table alone (``dttmm report --from-data`` redraws them).
Each animation is an H.264 video with a still frame as its poster and fallback image, or an
animated GIF where ffmpeg is absent; the section states how long the drawing took.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from .render import Section

__all__ = ["MOTION", "motion_table", "report_cases", "section"]

# methods: None draws the first DT-TMM method and the rigid baseline(s) of the registry, for contrast
MOTION = dict(k=8, h=1e-3, points=13, fps=20.0, max_frames=120, methods=None)
FIGSIZE, DPI = (6.4, 6.4), 100  # 640 px square: readable at the page's width
BEND_SHARE = 0.06  # the drawn bending peaks at this share of the arm's reach (see exaggeration)


@dataclass
class Motion:
    """What the drawing needs of a Result: t (nt,), link_shapes (nt, n, p, 2), end_effector (nt, 2)."""

    t: np.ndarray
    link_shapes: np.ndarray
    end_effector: np.ndarray
    meta: dict = field(default_factory=dict)


def report_cases(ctx) -> dict:
    """The cases to animate: the plan's own cases and the closed-loop study's case."""
    names = list(ctx.plan.durations)
    if "control" in ctx.plan.studies:
        from experiments.studies import control

        names.append(control.load(ctx.plan.studies["control"]).name)
    return {n: ctx.cases[n] for n in dict.fromkeys(names) if n in ctx.cases}


def motion_table(cases: dict, settings: dict | None = None, log=print) -> dict:
    """{"motion": table} of the frames of every case (see the module docstring); a method that
    fails on a case is left out of that case with a log line."""
    from dttmm.animate import frame_indices
    from experiments import methods

    s = {**MOTION, **(settings or {})}
    if s["methods"] is None:
        s["methods"] = (*methods.by_role("subject")[:1], *methods.by_role("baseline"))
    t0 = time.perf_counter()
    rows = []
    for name, case in cases.items():
        spatial = methods.is_spatial(case)
        for m in s["methods"]:
            try:
                r = methods.run(m, case, s["k"], s["h"], shape_points=s["points"])
            except Exception as exc:  # noqa: BLE001 - one missing animation must not stop the report
                log(f"motion: {m} on {name} skipped ({type(exc).__name__}: {exc})")
                continue
            if getattr(r, "link_shapes", None) is None or r.link_shapes.shape[-1] != (3 if spatial else 2):
                log(f"motion: {m} on {name} skipped (its result has no link shapes of this arm)")
                continue
            idx = frame_indices(r.t, s["fps"], 1.0, s["max_frames"])
            sh = r.link_shapes[idx]
            f, i, j = np.meshgrid(
                np.arange(idx.size), np.arange(sh.shape[1]), np.arange(sh.shape[2]), indexing="ij"
            )
            rows.append(
                pd.DataFrame(
                    {
                        "case": name,
                        "method": m,
                        "k": int(s["k"]) if methods.uses_k(m) else -1,
                        "h": float(s["h"]),
                        "frame": f.ravel(),
                        "t": r.t[idx][f.ravel()],
                        "link": i.ravel() + 1,
                        "point": j.ravel() + 1,
                        "x": sh[..., 0].ravel(),
                        "y": sh[..., 1].ravel(),
                        "z": sh[..., 2].ravel() if spatial else np.nan,
                    }
                )
            )
    cols = ["case", "method", "k", "h", "frame", "t", "link", "point", "x", "y", "z"]
    log(f"motion: {len(rows)} runs with link shapes in {time.perf_counter() - t0:.1f} s")
    return {"motion": pd.concat(rows, ignore_index=True) if rows else pd.DataFrame(columns=cols)}


def _motions(df: pd.DataFrame) -> dict:
    """{method: Motion} of one case's rows."""
    out = {}
    for m, g in df.groupby("method", sort=False):
        g = g.sort_values(["frame", "link", "point"])
        nf, n, p = g.frame.nunique(), g.link.nunique(), g.point.nunique()
        xyz = ["x", "y", "z"] if "z" in g and g.z.notna().all() else ["x", "y"]
        sh = g[xyz].to_numpy().reshape(nf, n, p, len(xyz))
        out[m] = Motion(g.t.to_numpy()[:: n * p], sh, sh[:, -1, -1].copy(), {"method": m})
    return out


def exaggeration(motions: dict, reach: float) -> float:
    """A round bending factor (1, 2, 5, 10, 20, …) that makes the largest deviation of a link
    from its chord about ``BEND_SHARE`` of the reach, or 1 when it already is."""
    from dttmm.animate import exaggerated

    dev = max(float(np.abs(exaggerated(m.link_shapes, 2.0) - m.link_shapes).max()) for m in motions.values())
    if dev <= 0:
        return 1.0
    want = BEND_SHARE * reach / dev
    steps = [1, 2, 5, 10, 20, 50, 100, 200, 500, 1000]
    return float(max([1] + [x for x in steps if x <= want]))


def section(inp) -> Section | None:
    """The "Motion" section from ``inp.tables["motion"]`` (None when there is no such table)."""
    df = inp.tables.get("motion")
    if df is None or not len(df):
        return None
    from dttmm import case_from_dict
    from dttmm.animate import arm_animation, ffmpeg_path, save, save_frame
    from experiments.methods import label, style

    t0 = time.perf_counter()
    cases = inp.meta.get("cases") or {}
    figs, text = [], []
    video = ffmpeg_path() is not None
    not_drawn = {}
    for name, g in df.groupby("case", sort=False):
        motions = _motions(g)
        spatial = next(iter(motions.values())).link_shapes.shape[-1] == 3
        case = case_from_dict(cases[name]) if name in cases and not spatial else None
        if case is not None:
            reach = sum(lk.beam.length for lk in case.model.links)
        else:
            first = next(iter(motions.values())).link_shapes[0]
            reach = float(np.linalg.norm(first[:, -1] - first[:, 0], axis=-1).sum())
        x = exaggeration(motions, reach)
        fps = MOTION["fps"]
        looks = {m: (label(m), style(m, i).color, style(m, i).linestyle) for i, m in enumerate(motions)}
        try:
            anim = arm_animation(
                motions,
                case,
                exaggerate=x,
                fps=fps,
                max_frames=None,
                title=name,
                figsize=FIGSIZE,
                dpi=DPI,
                styles=looks,
            )
        except Exception as exc:  # noqa: BLE001 - a drawing this dttmm.animate cannot make yet
            not_drawn[name] = f"{type(exc).__name__}: {exc}"
            continue
        stem = f"motion_{name}"
        inp.fig_dir.mkdir(parents=True, exist_ok=True)
        save_frame(anim, len(anim.frame_times) - 1, inp.fig_dir / f"{stem}.png")
        path = save(anim, inp.fig_dir / (f"{stem}.mp4" if video else f"{stem}.gif"), fps=fps)
        d = g.iloc[0]
        who = " and ".join(label(m) for m in motions)
        scale = f"bending between the joints drawn ×{x:g}, joints and tips at their true positions"
        cap = (
            f"{name}: {who} (DT-TMM k = {d.k}, h = {d.h:g} s), {g.frame.nunique()} frames in real time"
            f"{', in 3-D' if spatial else ''}; {scale if x != 1 else 'true scale'}; thin line: end-effector trace."
        )
        figs.append((f"figures/{path.name}", cap))
    took = time.perf_counter() - t0
    text.append(
        f"Every case of the studies animated from the stored frames (table motion), spatial arms in "
        f"3-D: links as their deflected centre lines (Result.link_shapes), the rigid model's straight "
        f"links for contrast (the benchmark problems have their own page). "
        f"Drawn and encoded in {took:.1f} s ({'H.264 video' if video else 'animated GIF, no ffmpeg here'})."
    )
    text += not_drawn_note(not_drawn)
    inp.meta["motion_render_s"] = took
    return Section("Motion", figs, text, [], "motion", "")


def not_drawn_note(not_drawn: dict) -> list[str]:
    """A sentence naming the cases of the motion table that could not be drawn, with the reason
    (none when every case was drawn)."""
    if not not_drawn:
        return []
    return ["Not animated: " + "; ".join(f"{n} ({why})" for n, why in not_drawn.items()) + "."]
