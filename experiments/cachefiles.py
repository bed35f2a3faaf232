"""Cache entries on disk that are verified on every read.

An entry is a JSON record plus, optionally, a parquet time history beside it. The record
carries its own key (so a file copied or renamed onto another entry's name is detected), the
sha256 of the parquet bytes, and a seal: the sha256 of its own canonical content (so an edited
record is detected). Files are written to unique temporary names in the same folder and moved
into place with ``os.replace`` (atomic), the parquet first and the record last, under an
exclusive lock of the folder; reads take a shared lock. A missing entry reads as None; a
damaged or mismatched one raises :class:`BadEntry` and the caller recomputes it.
"""

from __future__ import annotations

import contextlib
import io
import json
import os
import tempfile
import warnings
from pathlib import Path

from .fingerprint import digest

try:  # POSIX; elsewhere entries are still verified, only concurrent writers are not serialised
    import fcntl
except ImportError:  # pragma: no cover
    fcntl = None

__all__ = [
    "BadEntry",
    "CacheWarning",
    "read_entry",
    "result_bytes",
    "result_from_bytes",
    "warn",
    "write_entry",
]

SEAL = "record_sha256"


class CacheWarning(UserWarning):
    """A cache entry was unreadable or did not match what was asked for; it is recomputed."""


class BadEntry(Exception):
    """A cache entry that must not be used; the message says why."""


def warn(path, why: str) -> None:
    """Report a discarded cache entry (a CacheWarning naming the file and the reason)."""
    warnings.warn(f"cache entry {path} discarded ({why}); recomputing it", CacheWarning, stacklevel=3)


@contextlib.contextmanager
def _locked(folder: Path, exclusive: bool):
    """Hold the folder's lock (exclusive for writers, shared for readers). A folder that
    cannot hold a lock file (read-only) is read without one: its entries are still verified."""
    f = None
    if fcntl is not None:
        try:
            if exclusive:
                folder.mkdir(parents=True, exist_ok=True)
            f = open(folder / ".lock", "a+")  # noqa: SIM115 -- closed below, after unlocking
        except OSError:
            if exclusive:
                raise
    try:
        if f is not None:
            fcntl.flock(f, fcntl.LOCK_EX if exclusive else fcntl.LOCK_SH)
        yield
    finally:
        if f is not None:
            fcntl.flock(f, fcntl.LOCK_UN)
            f.close()


def _atomic_write(path: Path, data: bytes) -> None:
    """Write to a temporary file unique to this process in the same folder, then rename."""
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(data)
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise


def result_bytes(result) -> bytes:
    """The parquet bytes of ``Result.to_frame()``."""
    buf = io.BytesIO()
    result.to_frame().to_parquet(buf)
    return buf.getvalue()


def result_from_bytes(data: bytes):
    """The Result stored as parquet bytes (a SpatialResult when the table has 3-D columns)."""
    import pandas as pd

    from dttmm import Result
    from dttmm.spatial import SpatialResult

    df = pd.read_parquet(io.BytesIO(data))
    return (SpatialResult if "end_effector_z" in df.columns else Result).from_frame(df)


def _sealed(record: dict) -> str:
    return digest({k: v for k, v in record.items() if k != SEAL})


def write_entry(jpath: Path, ppath: Path, record: dict, history: bytes | None) -> dict:
    """Store ``record`` (and ``history`` parquet bytes, when given) as one verified entry.

    ``record`` must hold its ``key``; the history's sha256 and the seal are added. Returns
    the record as stored.
    """
    import hashlib

    record = dict(record)
    record["history_sha256"] = hashlib.sha256(history).hexdigest() if history is not None else None
    record[SEAL] = _sealed(record)
    text = json.dumps(record, indent=1).encode()
    with _locked(jpath.parent, exclusive=True):
        if history is not None:
            _atomic_write(ppath, history)
        _atomic_write(jpath, text)
    return record


def read_entry(jpath: Path, ppath: Path, key: str) -> tuple[dict, bytes | None] | None:
    """(record, history bytes or None) of a verified entry; None when there is no entry.

    Raises
    ------
    BadEntry
        unreadable record, a record of another key, an edited record, a missing or changed
        history.
    """
    import hashlib

    with _locked(jpath.parent, exclusive=False):
        if not jpath.exists():
            return None
        try:
            record = json.loads(jpath.read_text())
        except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
            raise BadEntry(f"unreadable record: {type(exc).__name__}") from None
        if not isinstance(record, dict) or record.get("key") != key:
            got = record.get("key") if isinstance(record, dict) else None
            raise BadEntry(f"made for another case content, code or run (key {got!r}, wanted {key!r})")
        if record.get(SEAL) != _sealed(record):
            raise BadEntry("record edited after it was written (seal does not match)")
        want = record.get("history_sha256")
        if want is None:
            return record, None
        try:
            data = ppath.read_bytes()
        except OSError:
            raise BadEntry("history file missing") from None
    if hashlib.sha256(data).hexdigest() != want:
        raise BadEntry("history file changed or truncated (sha256 does not match)")
    return record, data
