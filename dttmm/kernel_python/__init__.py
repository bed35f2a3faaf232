"""The DT-TMM kernel, uncompiled: the source files of :mod:`dttmm.kernel`, imported a second
time under this package name, where ``njit`` is the identity (see :mod:`dttmm.kernel._jit`).

This is the engine "python": the same algorithm as the compiled kernel, line for line, for
debugging and for installations without numba.
"""

from pathlib import Path

# submodules of this package are the files of dttmm/kernel/
__path__ = [str(Path(__file__).resolve().parent.parent / "kernel")]
