"""The spatial DT-TMM kernel (docs/spatial.md): kinematics, the Riccati sweep, energy and the
time loop, compiled by numba (see :mod:`._jit`)."""
