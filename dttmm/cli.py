"""Command line: ``dttmm simulate``, ``dttmm urdf``, ``dttmm report``."""
from __future__ import annotations

import argparse
import sys


def _iterations(text: str):
    if text == "auto":
        return "auto"
    try:
        return int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"--iterations = {text!r}: an integer ≥ 0 or 'auto'") from None


def main(argv=None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    if argv and argv[0] == "report":  # the report has its own parser (reports/cli.py)
        from reports.cli import main as report_main

        return report_main(argv[1:])
    if argv and argv[0] == "urdf":
        from .urdf import main as urdf_main

        return urdf_main(argv[1:])
    p = argparse.ArgumentParser(prog="dttmm", description=__doc__)
    sub = p.add_subparsers(dest="cmd", required=True)
    s = sub.add_parser("simulate", help="simulate a case with DT-TMM and write its results")
    s.add_argument("case", help="case TOML file")
    s.add_argument("--elements", "-k", type=int, required=True, help="elements per link")
    s.add_argument("--h", type=float, required=True, help="time step (s)")
    s.add_argument("--integrator", default="newmark", help="newmark | generalized-alpha | rk4")
    s.add_argument("--sweep", default="riccati", help="riccati | plain")
    s.add_argument("--iterations", type=_iterations, default=None,
                   help="corrections per step: an integer m (m + 1 sweeps), 'auto', or omit to converge")
    s.add_argument("--engine", default=None, choices=["numba", "numpy"], help="default: numba when installed")
    s.add_argument("--format", default="csv", choices=["csv", "parquet"])
    s.add_argument("--out", default="out/simulate", help="output folder")
    sub.add_parser("urdf", help="print the rigid arm of a case as URDF")
    sub.add_parser("report", help="run the studies and build the report")
    a = p.parse_args(argv)
    from .simulate_cli import run_simulate

    return run_simulate(a)


if __name__ == "__main__":
    raise SystemExit(main())
