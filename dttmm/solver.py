"""(being written) DT-TMM simulate / accelerations."""


def simulate(case, *, elements_per_link, h, integrator="newmark", **options):
    raise NotImplementedError


def accelerations(case, elements_per_link, q, qd, t=0.0):
    raise NotImplementedError
