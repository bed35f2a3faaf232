"""The old module name of the benchmark-problems study, :mod:`experiments.studies.problems`.

Kept so that ``python -m experiments.studies.benchmarks`` (the study's name, which plans, tables
and the methods registry keep) and imports of this module go on working: importing it gives the
problems module itself.
"""

import sys

from . import problems

if __name__ == "__main__":  # python -m experiments.studies.benchmarks [--quick|--full] ...
    from experiments.study import study_main

    raise SystemExit(study_main(problems.NAME))
sys.modules[__name__] = problems
