"""Exit codes and the one-line argument parser shared by the ``dttmm`` subcommands."""

from __future__ import annotations

import argparse

__all__ = ["EXIT_OK", "EXIT_FAILED", "EXIT_INPUT", "EXIT_NOT_OK", "OneLineParser"]

#: 0 ok, 1 the simulation failed, 2 bad input, 3 finished but unconverged / ill-conditioned.
EXIT_OK, EXIT_FAILED, EXIT_INPUT, EXIT_NOT_OK = 0, 1, 2, 3


class OneLineParser(argparse.ArgumentParser):
    """An argument parser whose errors are one line on stderr (exit 2), without the usage block."""

    def error(self, message: str):
        self.exit(EXIT_INPUT, f"{self.prog}: bad option: {message} (see {self.prog} --help)\n")
