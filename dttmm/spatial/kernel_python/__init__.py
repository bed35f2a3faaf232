"""The spatial DT-TMM kernel, uncompiled: the source files of :mod:`dttmm.spatial.kernel`,
imported a second time under this package name, where ``njit`` is the identity (engine
"python")."""

from pathlib import Path

__path__ = [str(Path(__file__).resolve().parent.parent / "kernel")]
