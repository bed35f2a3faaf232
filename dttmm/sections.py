"""Cross-section calculator: the beam data of a spatial link (docs/urdf.md "Sections") from a
shape and a material.

:func:`section_properties` gives ``EA``, ``GJ``, ``EIy``, ``EIz`` (N, N·m²), ``rhoA`` (kg/m)
and ``rhoJ``, ``rhoIy``, ``rhoIz`` (kg·m) — the keys of :class:`dttmm.spatial.SpatialSection`
— for a homogeneous section of one of these shapes (section axes: y "width", z "height";
EIz bends along y, EIy along z, docs/spatial.md §1):

* ``tube``: ``outer_diameter``, ``wall`` (m) — I = π(r_o⁴ − r_i⁴)/4 about y and z, torsion
  constant J = 2I (a circular section does not warp);
* ``rectangle``: ``width`` (along y), ``height`` (along z), optional ``wall`` (a hollow
  rectangle of that wall thickness) — solid: Iz = h b³/12, Iy = b h³/12, torsion constant of
  the solid rectangle (Roark's Formulas for Stress and Strain, table 10.1, case 4:
  J = a b³ (1/3 − 0.21 (b/a)(1 − b⁴/(12 a⁴))), a ≥ b the long and short sides); hollow: the
  inertias by difference, torsion by Bredt's thin-walled closed section
  J = 4 A_m² t / p_m (A_m, p_m the area and perimeter enclosed by the wall's mid-line);
* ``i_beam``: ``width`` (flanges, along y), ``height`` (along z, the web), ``flange`` and
  ``web`` thicknesses (m) — Iy = (b h³ − (b − t_w)(h − 2t_f)³)/12,
  Iz = (2 t_f b³ + (h − 2t_f) t_w³)/12, open thin-walled torsion
  J = (2 b t_f³ + (h − 2t_f) t_w³)/3.

Mass per length ρA and the mass moments per length ρIy = ρ·Iy, ρIz = ρ·Iz, ρJ = ρ(Iy + Iz)
(the polar moment of the area, the rotary inertia about the beam axis).

A material is ``E`` (Pa), ``G`` (Pa) or Poisson's ratio ``nu`` (G = E/(2(1 + ν))), ``rho``
(kg/m³), or one of the named materials of :data:`MATERIALS`.
"""

from __future__ import annotations

import math
from typing import Annotated

from pydantic import Field, Strict, ValidationError

from .errors import InputError
from .schema import Positive, _short, _Strict, input_error

__all__ = ["MATERIALS", "SHAPES", "Material", "material", "section_properties"]

Ratio = Annotated[float, Strict(), Field(gt=-1.0, lt=0.5, allow_inf_nan=False)]


class Material(_Strict):
    """An isotropic material: ``E`` (Pa), ``G`` (Pa) or ``nu``, ``rho`` (kg/m³)."""

    E: Positive
    G: Positive | None = None
    nu: Ratio | None = None
    rho: Positive


#: Named materials (E, G in Pa; rho in kg/m³) and where their values come from.
MATERIALS = {
    # ASM Aerospace Specification Metals data sheet of 6061-T6 (matweb.com): E = 68.9 GPa,
    # shear modulus 26 GPa, density 2.70 g/cm³
    "aluminium": {"E": 68.9e9, "G": 26.0e9, "rho": 2700.0},
    # structural carbon steel (EN 1993-1-1 §3.2.6: E = 210 GPa, G = 81 GPa; density 7850 kg/m³,
    # EN 1991-1-1 table A.4)
    "steel": {"E": 210.0e9, "G": 81.0e9, "rho": 7850.0},
    # a quasi-isotropic carbon-fibre/epoxy laminate (T300/5208, [0/±45/90]s): E ≈ 54 GPa,
    # ν ≈ 0.3 (G = E/2.6 ≈ 21 GPa), density 1600 kg/m³ (Tsai & Hahn, Introduction to Composite
    # Materials, the laminate's in-plane moduli); the isotropic stand-in of a wound tube
    "carbon-fibre": {"E": 54.0e9, "G": 54.0e9 / 2.6, "rho": 1600.0},
}
MATERIALS["aluminium-6061-t6"] = MATERIALS["aluminium"]


class Tube(_Strict):
    outer_diameter: Positive
    wall: Positive


class Rectangle(_Strict):
    width: Positive
    height: Positive
    wall: Positive | None = None


class IBeam(_Strict):
    width: Positive
    height: Positive
    flange: Positive
    web: Positive


SHAPES = {"tube": Tube, "rectangle": Rectangle, "i_beam": IBeam}


def material(spec, where: str = "material") -> tuple[float, float, float]:
    """(E, G, rho) of a named material (a key of :data:`MATERIALS`) or a table
    ``{E, G | nu, rho}``."""
    if isinstance(spec, str):
        key = spec.strip().lower().replace("_", "-").replace("aluminum", "aluminium")
        key = {"carbon-fiber": "carbon-fibre", "cfrp": "carbon-fibre"}.get(key, key)
        if key not in MATERIALS:
            names = ", ".join(n for n in MATERIALS if n != "aluminium-6061-t6")
            raise InputError(where, spec, f"is not a known material ({names}; or a table {{E, G, rho}})")
        m = MATERIALS[key]
        return m["E"], m["G"], m["rho"]
    if not isinstance(spec, dict):
        raise InputError(where, _short(spec), "must be a material name or a table {E, G (or nu), rho}")
    try:
        m = Material.model_validate(spec)
    except ValidationError as exc:
        raise input_error(exc, Material, where) from None
    if (m.G is None) == (m.nu is None):
        raise InputError(where, _short(spec), "give exactly one of G and nu")
    G = m.G if m.G is not None else m.E / (2.0 * (1.0 + m.nu))
    return m.E, G, m.rho


def _rect_torsion(a: float, b: float) -> float:
    a, b = max(a, b), min(a, b)
    return a * b**3 * (1.0 / 3.0 - 0.21 * (b / a) * (1.0 - b**4 / (12.0 * a**4)))


def _geometry(shape: str, dims: dict, where: str) -> tuple[float, float, float, float]:
    """Area A, Iy, Iz (second moments about y and z) and the torsion constant J."""
    if shape not in SHAPES:
        raise InputError(where, shape, f"is not a section shape ({', '.join(SHAPES)})")
    try:
        d = SHAPES[shape].model_validate(dims)
    except ValidationError as exc:
        raise input_error(exc, SHAPES[shape], f"{where}.{shape}") from None
    w = f"{where}.{shape}"
    if shape == "tube":
        ro = d.outer_diameter / 2
        if not d.wall < ro:
            raise InputError(f"{w}.wall", d.wall, f"must be less than the outer radius {ro:g} m")
        ri = ro - d.wall
        area = math.pi * (ro**2 - ri**2)
        i = math.pi / 4 * (ro**4 - ri**4)
        return area, i, i, 2 * i
    if shape == "rectangle":
        b, h = d.width, d.height
        if d.wall is None:
            return b * h, b * h**3 / 12, h * b**3 / 12, _rect_torsion(b, h)
        t = d.wall
        if not 2 * t < min(b, h):
            raise InputError(f"{w}.wall", t, f"must be less than half the smaller side {min(b, h) / 2:g} m")
        bi, hi = b - 2 * t, h - 2 * t
        area = b * h - bi * hi
        iy = (b * h**3 - bi * hi**3) / 12
        iz = (h * b**3 - hi * bi**3) / 12
        am, pm = (b - t) * (h - t), 2 * ((b - t) + (h - t))
        return area, iy, iz, 4 * am**2 * t / pm
    b, h, tf, tw = d.width, d.height, d.flange, d.web
    if not 2 * tf < h:
        raise InputError(f"{w}.flange", tf, f"must be less than half the height {h / 2:g} m")
    if not tw <= b:
        raise InputError(f"{w}.web", tw, f"must not exceed the width {b:g} m")
    hw = h - 2 * tf
    area = 2 * b * tf + hw * tw
    iy = (b * h**3 - (b - tw) * hw**3) / 12
    iz = (2 * tf * b**3 + hw * tw**3) / 12
    return area, iy, iz, (2 * b * tf**3 + hw * tw**3) / 3


def section_properties(
    shape, material_spec, where: str = "section", material_where: str = "material"
) -> dict[str, float]:
    """The beam data (EA, GJ, EIy, EIz, rhoA, rhoJ, rhoIy, rhoIz; SI) of a section ``shape`` —
    a one-entry table ``{tube = {...}}``, ``{rectangle = {...}}`` or ``{i_beam = {...}}`` — of
    ``material_spec`` (a name of :data:`MATERIALS` or ``{E, G | nu, rho}``)."""
    if not isinstance(shape, dict) or len(shape) != 1:
        raise InputError(where, _short(shape), f"must be one of {{{' | '.join(SHAPES)} = {{...}}}}")
    ((name, dims),) = shape.items()
    if not isinstance(dims, dict):
        raise InputError(f"{where}.{name}", _short(dims), "must be a table of the shape's dimensions")
    area, iy, iz, j = _geometry(name, dims, where)
    E, G, rho = material(material_spec, material_where)
    return {
        "EA": E * area,
        "GJ": G * j,
        "EIy": E * iy,
        "EIz": E * iz,
        "rhoA": rho * area,
        "rhoJ": rho * (iy + iz),
        "rhoIy": rho * iy,
        "rhoIz": rho * iz,
    }
