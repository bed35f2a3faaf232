"""The report's case descriptions: one parameter table per case (links, drives) and a sentence
with gravity, duration and output grid, from the case data stored in the report's metadata."""

from __future__ import annotations

import pandas as pd

from .render import Section

__all__ = ["case_section", "drive_text", "link_table"]

_NONE = "–"


def _g(v) -> str:
    return _NONE if v is None else f"{float(v):.4g}"


def link_table(case: dict) -> pd.DataFrame:
    """One row per link (base first) with its beam data, hub, payload and drive, SI units."""
    if case.get("kind") == "spatial":
        return spatial_link_table(case)
    rows = []
    drives = case["scenario"]["drives"]
    for i, link in enumerate(case["model"]["links"]):
        hub, pay = link.get("hub") or {}, link.get("payload") or {}
        rows.append(
            {
                "link": i + 1,
                "L (m)": _g(link["length"]),
                "EI (N·m²)": _g(link["EI"]),
                "ρA (kg/m)": _g(link["rhoA"]),
                "EA (N)": _g(link.get("EA")) if link.get("EA") is not None else "inextensible",
                "damping (s)": _g(link.get("damping", 0.0)),
                "hub m (kg), J (kg·m²)": f"{_g(hub['mass'])}, {_g(hub['inertia'])}" if hub else _NONE,
                "payload m (kg), J (kg·m²)": f"{_g(pay['mass'])}, {_g(pay['inertia'])}" if pay else _NONE,
                "drive of joint": drive_text(drives[i]) if i < len(drives) else _NONE,
            }
        )
    return pd.DataFrame(rows)


def _diag(m) -> str:
    """A 3×3 inertia as its diagonal, or in full when it has products of inertia."""
    off = any(m[r][c] for r in range(3) for c in range(3) if r != c)
    return _value([[float(x) for x in r] for r in m]) if off else _value([float(m[i][i]) for i in range(3)])


def _section_columns(link: dict) -> dict:
    return {
        "EA, GJ (N, N·m²)": f"{_g(link.get('EA')) if link.get('EA') is not None else 'inextensible'}, "
        f"{_g(link['GJ'])}",
        "EIy, EIz (N·m²)": f"{_g(link['EIy'])}, {_g(link['EIz'])}",
        "ρA (kg/m); ρJ, ρIy, ρIz (kg·m)": f"{_g(link['rhoA'])}; {_g(link['rhoJ'])}, {_g(link['rhoIy'])}, "
        f"{_g(link['rhoIz'])}",
        "roll (rad), damping (s)": f"{_g(link['roll'])}, {_g(link['damping'])}",
    }


def _rigid_columns(body: dict) -> dict:
    """A rigid link's body in the section's columns: no stiffness, its mass, centre and inertia."""
    return {
        "EA, GJ (N, N·m²)": "rigid",
        "EIy, EIz (N·m²)": "rigid",
        "ρA (kg/m); ρJ, ρIy, ρIz (kg·m)": f"rigid body: m {_g(body['mass'])} kg, centre {_value(body['com'])} m, "
        f"J {_diag(body['inertia'])} kg·m²",
        "roll (rad), damping (s)": _NONE,
    }


def spatial_link_table(case: dict) -> pd.DataFrame:
    """A spatial case's links: joint frame and axis, the section's stiffnesses and inertias,
    hub and payload (inertias as diagonals when they have no products), drive; SI units."""
    rows, drives = [], list(case["scenario"]["drives"])
    for i, link in enumerate(case["model"]["links"]):
        j, hub, pay = link["joint"], link.get("hub") or {}, link.get("payload") or {}
        drive = _NONE if j["locked"] else (drive_text(drives.pop(0)) if drives else _NONE)
        rows.append(
            {
                "link": i + 1,
                "joint axis; origin xyz (m), rpy (rad)": "locked"
                if j["locked"]
                else _value(j["axis"]) + f"; {_value(j['origin_xyz'])}, {_value(j['origin_rpy'])}",
                "L (m)": _g(link["length"]),
                **(_rigid_columns(link["rigid"]) if "rigid" in link else _section_columns(link)),
                "hub m (kg), J (kg·m²)": f"{_g(hub['mass'])}, {_diag(hub['inertia'])}" if hub else _NONE,
                "payload m (kg), offset (m), J (kg·m²)": f"{_g(pay['mass'])}, {_value(pay['offset'])}, "
                f"{_diag(pay['inertia'])}"
                if pay
                else _NONE,
                "drive of joint": drive,
            }
        )
    return pd.DataFrame(rows)


def drive_text(d: dict) -> str:
    """``torque, sine (amplitude = 1, frequency = 1, until = 1)``; initial values if non-zero."""
    skip = {"kind", "law", "initial_angle", "initial_rate"}
    params = ", ".join(f"{k} = {_value(v)}" for k, v in d.items() if k not in skip)
    init = [f"{k} = {_value(d[k])}" for k in ("initial_angle", "initial_rate") if d.get(k)]
    unit = "N·m" if d["kind"] == "torque" else "rad"
    text = f"{d['kind']} ({unit}), {d['law']}" + (f" ({params})" if params else "")
    return text + (f"; {', '.join(init)}" if init else "")


def _value(v) -> str:
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(_value(x) for x in v) + "]"
    return f"{v:.4g}" if isinstance(v, float) else str(v)


def case_section(meta: dict) -> Section | None:
    """Section "Cases": the parameters of every case of the report (None if not recorded)."""
    cases = meta.get("cases") or {}
    if not cases:
        return None
    text, tables = [], []
    files = meta.get("case_files") or {}
    for name, c in cases.items():
        s, g = c["scenario"], c["model"]["gravity"]
        grav = "none" if not any(g) else "(" + ", ".join(_value(float(x)) for x in g) + ") m/s²"
        src = f" from {files[name]}" if name in files else ""
        kind = "a spatial arm, " if c.get("kind") == "spatial" else ""
        text.append(
            f"{name}{src}: {kind}{len(c['model']['links'])} link(s), gravity {grav}, simulated for "
            f"{_value(float(s['duration']))} s with output every {_value(float(s['output_step']) * 1e3)} ms."
        )
        tables.append((f"case_{name}", link_table(c), f"Parameters of {name} (SI units), one row per link"))
        out = (meta.get("sitting_out") or {}).get(name) or {}
        if out:
            text.append(
                f"{name} is a spatial arm: the studies run it with every method that models it; "
                + "; ".join(f"{m} sits it out ({why})" for m, why in out.items())
                + "."
            )
        runs = {
            (study, m): why
            for study, by_case in (meta.get("sitting_out_runs") or {}).items()
            for m, why in by_case.get(name, {}).items()
        }
        if runs:
            text.append(
                f"Sat out on {name} before running: "
                + "; ".join(
                    f"{m} in the {study.replace('_', '-')} study ({why})" for (study, m), why in runs.items()
                )
                + "."
            )
    text.append(
        "Torque-driven joints follow the torque law given; motion-driven joints follow the angle law and "
        "their torque is an output. Every method solves the same case: the same links, drives and output "
        "grid; only the discretisation (elements per link k, step h) differs."
    )
    return Section("Cases", [], text, tables, "cases")
