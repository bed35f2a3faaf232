"""What the ``dttmm`` subcommands share: exit codes, the one-line argument parser, the options
several take (:func:`add_option`), the number type of options and the PNG figures they write."""

from __future__ import annotations

import argparse
import sys

__all__ = [
    "EXIT_FAILED",
    "EXIT_INPUT",
    "EXIT_NOT_OK",
    "EXIT_OK",
    "OPTIONS",
    "OneLineParser",
    "add_option",
    "bad_input",
    "number",
    "pyplot",
    "save_figure",
]

#: 0 ok, 1 the simulation failed, 2 bad input, 3 finished but unconverged / ill-conditioned.
EXIT_OK, EXIT_FAILED, EXIT_INPUT, EXIT_NOT_OK = 0, 1, 2, 3


class OneLineParser(argparse.ArgumentParser):
    """An argument parser whose errors are one line on stderr (exit 2), without the usage block."""

    def error(self, message: str):
        self.exit(EXIT_INPUT, f"{self.prog}: bad option: {message} (see {self.prog} --help)\n")


def bad_input(exc) -> int:
    """Report the :class:`dttmm.InputError` ``exc`` as one line on stderr; the exit code 2."""
    print(f"dttmm: bad input: {exc}", file=sys.stderr)
    return EXIT_INPUT


def number(text: str) -> float:
    """An option's value as a float (argparse type); a one-line error when it is not a number."""
    try:
        return float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None


#: the options several subcommands take: name -> (flags, add_argument keywords)
OPTIONS = {
    "elements": (("--elements", "-k"), {"type": int, "help": "elements per link"}),
    "h": (("--h",), {"type": number, "help": "time step (s)"}),
    "strain": (
        ("--strain",),
        {
            "default": "linear",
            "choices": ["linear", "second-order"],
            "help": "axial strain of the elements (default linear)",
        },
    ),
    "out": (("--out",), {"help": "output folder (created before the run)"}),
}


def add_option(p: argparse.ArgumentParser, name: str, **overrides) -> None:
    """Add the shared option ``name`` of :data:`OPTIONS` to ``p``, with ``overrides`` (a
    default, ``required``, another help text)."""
    flags, kw = OPTIONS[name]
    p.add_argument(*flags, **{**kw, **overrides})


def pyplot():
    """matplotlib.pyplot on the file-only Agg backend (the subcommands write PNG files)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def save_figure(fig, axes, path, title: str = ""):
    """Grid and legend on each of ``axes``, ``title`` over the first; write the PNG ``path``
    (120 dpi), close the figure and return ``path``."""
    for ax in axes:
        ax.grid(alpha=0.3)
        ax.legend(loc="best", fontsize=8)
    axes[0].set_title(title)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    pyplot().close(fig)
    return path
