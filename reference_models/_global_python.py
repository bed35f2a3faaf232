"""The global solver's engine, uncompiled: the source file of :mod:`reference_models._global_numba`
imported a second time under this module's name, where ``njit`` is the identity.

This is the engine "python" of :func:`reference_models.global_newmark.simulate` (alias
"numpy"): the same time loop, assembly and solve as the compiled engine, line for line, for
debugging, for Python user laws and for installations without numba.
"""

from pathlib import Path

_SOURCE = Path(__file__).resolve().with_name("_global_numba.py")
_doc = __doc__
# run the engine's source in this module's namespace: its PURE switch reads this module's name
exec(compile(_SOURCE.read_text(encoding="utf-8"), str(_SOURCE), "exec"))  # noqa: S102
__doc__ = _doc
del _doc
