"""The DT-TMM kernel: the whole time loop of :func:`dttmm.simulate` as scalar code that numba
compiles (or that runs as plain Python, see :mod:`dttmm.kernel_python`).

Modules, in the order of the algorithm:

* :mod:`~dttmm.kernel.layout` — the constant :class:`Model` and the per-run :class:`Data`
  workspace (named tuples of arrays), and the named codes;
* :mod:`~dttmm.kernel.element` — the element terms (one function for every pass), frame
  angles, known elastic forces, effective elastic mass;
* :mod:`~dttmm.kernel.riccati` and :mod:`~dttmm.kernel.plain` — the two sweeps;
* :mod:`~dttmm.kernel.feedback` — closed-loop (pd/pid, user) joint torques inside the loop;
* :mod:`~dttmm.kernel.loop` — predictor, iteration control, Newmark and RK4 steps, the loop;
* :mod:`~dttmm.kernel.recorder` — output sampling (cubic Hermite) and energy;
* :mod:`~dttmm.kernel.driver` — the Python side: builds the records, evaluates the drive laws,
  calls the loop in chunks, assembles the :class:`dttmm.Result`.

Importing this package imports none of its modules (so that a module can import one part
without the rest).
"""
