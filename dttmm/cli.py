"""Command line: ``dttmm simulate``, ``dttmm modes``, ``dttmm animate``, ``dttmm urdf``,
``dttmm report``, ``dttmm validate``.

Exit codes: 0 — done, status "ok"; 1 — the simulation failed (the partial result is written);
2 — bad input (one line on stderr naming the field or option); 3 — the run finished but its
status is not "ok" ("unconverged" or "ill-conditioned"; the result is written, the warnings printed).
"""

from __future__ import annotations

import argparse
import importlib
import os
import re
import socket
import sys

from .cliparse import (
    EXIT_FAILED,
    EXIT_INPUT,
    EXIT_NOT_OK,
    EXIT_OK,
    OneLineParser,
    add_option,
    bad_input,
    number,
)

__all__ = ["EXIT_FAILED", "EXIT_INPUT", "EXIT_NOT_OK", "EXIT_OK", "OneLineParser", "main", "simulate_parser"]


def _iterations(text: str):
    if text == "auto":
        return "auto"
    try:
        return int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"--iterations = {text!r}: an integer ≥ 0 or 'auto'") from None


def simulate_parser() -> argparse.ArgumentParser:
    p = OneLineParser(
        prog="dttmm simulate",
        description="Simulate a case with DT-TMM and write its table, a plot and meta.json.",
        epilog=__doc__.split("\n", 2)[2],
    )
    p.add_argument("case", help="case TOML file, planar or spatial (format: docs/cases.md)")
    add_option(p, "elements", required=True)
    add_option(p, "h", required=True)
    p.add_argument("--integrator", default="newmark", help="newmark | generalized-alpha | rk4")
    p.add_argument("--sweep", default="riccati", help="riccati | plain")
    iterations = "corrections per step: an integer m (m + 1 sweeps), 'auto', or omit to converge"
    p.add_argument("--iterations", type=_iterations, default=None, help=iterations)
    p.add_argument("--tol", type=number, default=1e-10, help="iteration tolerance (default 1e-10)")
    rho_inf = "spectral radius at infinity of generalized-alpha (default 0.9)"
    p.add_argument("--rho-inf", type=number, default=None, help=rho_inf)
    add_option(p, "strain")
    p.add_argument(
        "--engine", default=None, choices=["numba", "python"], help="default: numba when installed"
    )
    p.add_argument(
        "--shape-points",
        type=int,
        default=0,
        help="record the link shapes at P points per link (for dttmm animate; default 0: none)",
    )
    p.add_argument(
        "--kernel",
        default=None,
        choices=["planar", "spatial"],
        help="default: the case's own (planar or spatial); spatial runs a planar case on the spatial kernel",
    )
    p.add_argument("--format", default="csv", choices=["csv", "parquet"])
    add_option(p, "out", default="out/simulate")
    return p


_ADDRESS = re.compile(
    r"^(?:(?P<proto>[a-z]+)://)?(?P<host>\[[0-9a-fA-F:]+\]|[^\s:/\[\]]+):(?P<port>\d{1,5})/?$"
)


def check_scheduler(value: str | None) -> str | None:
    """Refuse a ``--scheduler`` that is neither 'serial' nor a reachable HOST:PORT address.

    Returns None when fine, else the one-line reason.
    """
    if value is None or value == "serial":
        return None
    m = _ADDRESS.match(value)
    if not m or not 0 < int(m["port"]) < 65536:
        return (
            f"--scheduler = {value!r}: must be 'serial' or a dask scheduler address such as tcp://HOST:PORT"
        )
    if (m["proto"] or "tcp") != "tcp":
        return None  # tls:// etc.: dask checks them itself
    try:
        with socket.create_connection((m["host"].strip("[]"), int(m["port"])), timeout=5.0):
            pass
    except OSError as exc:
        return f"--scheduler = {value!r}: cannot reach the scheduler ({exc.strerror or exc})"
    return None


def _scheduler_arg(argv: list[str]) -> str | None:
    for i, a in enumerate(argv):
        if a == "--scheduler":
            return argv[i + 1] if i + 1 < len(argv) else None
        if a.startswith("--scheduler="):
            return a.split("=", 1)[1]
    return None


def _report(argv: list[str]) -> int:
    """``dttmm report``: the report harness (package ``reports``), imported only now."""
    why = check_scheduler(_scheduler_arg(argv))
    if why:
        print(f"dttmm report: bad option: {why}", file=sys.stderr)
        return EXIT_INPUT
    try:
        report_cli = importlib.import_module("reports.cli")
    except ModuleNotFoundError as exc:
        if exc.name and exc.name.split(".")[0] in ("reports", "experiments"):
            print(
                "dttmm report: the report harness is not installed (packages 'reports' and "
                "'experiments' of the source tree); run it from a checkout",
                file=sys.stderr,
            )
            return EXIT_INPUT
        raise
    return report_cli.main(argv)


def _dispatch(argv: list[str]) -> int:
    if argv and argv[0] == "report":
        return _report(argv[1:])
    if argv and argv[0] == "validate":  # the validation suite (experiments.validate), from a checkout
        return importlib.import_module("experiments.validate").main(argv[1:])
    if argv and argv[0] == "urdf":
        from .urdf import main as urdf_main

        return urdf_main(argv[1:])
    if argv and argv[0] == "modes":
        from .modes_cli import modes_parser, run_modes

        return run_modes(modes_parser().parse_args(argv[1:]))
    if argv and argv[0] == "animate":
        from .animate_cli import animate_parser, run_animate

        return run_animate(animate_parser().parse_args(argv[1:]))
    if argv and argv[0] == "simulate":
        from .simulate_cli import run_simulate

        return run_simulate(simulate_parser().parse_args(argv[1:]))
    p = OneLineParser(prog="dttmm", description=__doc__)
    sub = p.add_subparsers(dest="cmd", required=True)
    sub.add_parser("simulate", help="simulate a case with DT-TMM and write its results")
    sub.add_parser("modes", help="natural frequencies and mode shapes of a case")
    sub.add_parser("urdf", help="print the rigid arm of a case as URDF")
    sub.add_parser("animate", help="animate a case (one or more methods) or a stored Result")
    sub.add_parser("report", help="run the studies and build the report")
    sub.add_parser("validate", help="check methods against published, closed-form and independent values")
    p.parse_args(argv)
    return EXIT_INPUT


def main(argv=None) -> int:
    """Entry point of ``dttmm``. Errors are one line on stderr; set DTTMM_DEBUG=1 to get the
    traceback of an unexpected one."""
    from .errors import InputError

    argv = list(sys.argv[1:] if argv is None else argv)
    try:
        return _dispatch(argv)
    except InputError as exc:
        return bad_input(exc)
    except SystemExit as exc:  # argparse: --help (0) or a bad option (2, message printed)
        return exc.code if isinstance(exc.code, int) else EXIT_INPUT
    except KeyboardInterrupt:
        print("dttmm: interrupted", file=sys.stderr)
        return 130
    except Exception as exc:  # a bug: one line unless asked for the traceback
        if os.environ.get("DTTMM_DEBUG"):
            raise
        msg = " ".join(str(exc).split())
        print(
            f"dttmm: internal error: {type(exc).__name__}: {msg} (DTTMM_DEBUG=1 shows the traceback)",
            file=sys.stderr,
        )
        return EXIT_FAILED


if __name__ == "__main__":
    raise SystemExit(main())
