"""The studies, one module each: ``tasks(ctx)`` lists the runs, ``analyse(ctx, table)`` turns
the run table into the study's tables; ``python -m experiments.studies.<name> --quick`` runs
one alone (``experiments.study.study_main``)."""

from . import control, convergence_h, convergence_k, cost, paper, problems, scheme, work_precision

STUDIES = {
    m.NAME: m for m in (convergence_k, convergence_h, work_precision, scheme, paper, cost, problems, control)
}

__all__ = ["STUDIES"]
