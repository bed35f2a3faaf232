"""What an engine prints during a run goes into that run's record, not to the terminal.

Engines with compiled cores (Exudyn's solver messages, for one) write to the process's file
descriptors 1 and 2 directly, past ``sys.stdout``; :func:`captured` redirects both descriptors
to a temporary file for the length of a run and hands back the text. One run at a time per
process (the sweep's workers have one thread each; the serial scheduler runs one after the
other), so the redirection never catches another run's output.
"""

from __future__ import annotations

import contextlib
import os
import re
import sys
import tempfile

__all__ = ["Printed", "captured"]

_MAX = 20_000  # characters kept of a run's console text (its end)


class Printed:
    """The console text of one run (available once the ``with`` block has ended)."""

    def __init__(self):
        self._text = ""

    def text(self) -> str:
        return self._text

    def last_line(self) -> str:
        lines = [x.strip() for x in self._text.splitlines() if x.strip() and set(x.strip()) != {"*"}]
        return lines[-1][:200] if lines else ""


@contextlib.contextmanager
def captured():
    """Redirect fds 1 and 2 (and ``sys.stdout``/``sys.stderr``) to a temporary file; yields a
    :class:`Printed` filled when the block ends. Where the descriptors cannot be duplicated
    (no real fds), the block runs uncaptured."""
    printed = Printed()
    try:
        saved = (os.dup(1), os.dup(2))
    except OSError:
        yield printed
        return
    with tempfile.TemporaryFile(mode="w+b") as tmp:
        for stream in (sys.stdout, sys.stderr):
            with contextlib.suppress(Exception):
                stream.flush()
        os.dup2(tmp.fileno(), 1)
        os.dup2(tmp.fileno(), 2)
        try:
            with contextlib.redirect_stdout(_Fd(1)), contextlib.redirect_stderr(_Fd(2)):
                yield printed
        finally:
            for stream in (sys.stdout, sys.stderr):
                with contextlib.suppress(Exception):
                    stream.flush()
            _flush_c_stdio()
            os.dup2(saved[0], 1)
            os.dup2(saved[1], 2)
            for fd in saved:
                os.close(fd)
            tmp.seek(0)
            text, logs = _split(tmp.read().decode("utf-8", "replace"))
            printed._text = text[-_MAX:]
            if logs:  # the worker's own log lines, written meanwhile by its other threads
                with contextlib.suppress(OSError):
                    os.write(2, logs.encode())


_LOG = re.compile(r"^\d{4}-\d\d-\d\d \d\d:\d\d:\d\d,\d{3} - (distributed|dask|tornado)[.\w]* - ")


def _split(text: str) -> tuple[str, str]:
    """(the run's own console text, the lines of Dask's logging among it)."""
    mine, logs = [], []
    for line in text.splitlines(keepends=True):
        (logs if _LOG.match(line) else mine).append(line)
    return "".join(mine), "".join(logs)


class _Fd:
    """A text stream writing straight to a file descriptor (Python-level prints of the run)."""

    def __init__(self, fd: int):
        self.fd = fd

    def write(self, s: str) -> int:
        os.write(self.fd, s.encode("utf-8", "replace"))
        return len(s)

    def flush(self) -> None:
        pass

    def isatty(self) -> bool:
        return False


def _flush_c_stdio() -> None:
    """Flush the C library's stdout buffer (C++ engines' ``printf``/``std::cout`` land there)."""
    with contextlib.suppress(Exception):
        import ctypes

        ctypes.CDLL(None).fflush(None)
