"""Linearisation and modes: the linear(ised) equations of the three-link arm, its natural
frequencies, and the mode shapes animated (``dttmm modes CASE -k K --animate`` does the same)."""

import numpy as np
from _gallery import CASES, QUICK, figure_path

import dttmm
from dttmm.animate import mode_animation, save

case = dttmm.load_case(CASES / "three_link.toml")
k = 4 if QUICK else 8
lin = dttmm.linearize(case, k)
print(f"linearised about t = 0: {lin.M.shape[0]} free coordinates; A is {lin.A.shape}")
m = dttmm.modes(case, k, n=6)
print("natural frequencies [Hz]:", np.round(m.frequencies, 3))
anim = mode_animation(m, case, frames=6 if QUICK else 36)
print("wrote", save(anim, figure_path("06_modes.gif")))
