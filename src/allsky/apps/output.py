"""Output files: checked before the work, written whole or not at all.

Every file a command writes (telemetry, JSON, figures, campaign records) goes
through :func:`write_atomic`: it is written under a temporary name in the
same directory and renamed over the target (``os.replace``), so that an
interruption or a full disk leaves the old file or the new one, never half
of one. :func:`check_output` refuses, before any mission is flown, a path
that could not be written; :class:`OutputError` names the option and the
path in one line. :func:`cap_workers` is the one rule for how many worker
processes a command starts.
"""

import errno
import os
from pathlib import Path


class OutputError(Exception):
    """An output path that cannot be written, named by its option (one line)."""

    def __init__(self, option, path, reason):
        self.option, self.path, self.reason = option, str(path), reason
        super().__init__(f"{option}: cannot write {path}: {reason}" if option
                         else f"cannot write {path}: {reason}")


def write_reason(e: OSError) -> str:
    """A short reason for a failed write, in words rather than errno text."""
    return {errno.ENOENT: "directory does not exist", errno.EACCES: "permission denied",
            errno.EPERM: "permission denied", errno.EROFS: "read-only file system",
            errno.ENOSPC: "no space left on the device", errno.EDQUOT: "disk quota exceeded",
            errno.EISDIR: "it is a directory", errno.ENOTDIR: "a parent is not a directory",
            errno.ENAMETOOLONG: "name too long"}.get(e.errno, e.strerror or str(e))


def _temporary(path: Path) -> Path:
    # Same directory (so that the rename is atomic), same suffix (writers pick the format
    # by it: .csv/.parquet, .png), hidden, and unique to this process.
    return path.with_name(f".{path.stem}.tmp{os.getpid()}{path.suffix}")


def write_atomic(path, data=None, writer=None, option=None) -> Path:
    """Write ``path`` whole or not at all, through a temporary file renamed over it.

    Parameters
    ----------
    path : path-like
        The file to write.
    data : str or bytes, optional
        The content (text is written as UTF-8).
    writer : callable, optional
        ``writer(temporary_path)`` writes the content itself (figures,
        Parquet); used instead of ``data``.
    option : str, optional
        The command-line option the path came from, for the error message.

    Returns
    -------
    pathlib.Path
        ``path``.

    Raises
    ------
    OutputError
        The file could not be written (the temporary file is removed).
    """
    path = Path(path)
    tmp = _temporary(path)
    try:
        if writer is not None:
            writer(tmp)
        else:
            with tmp.open("wb") as f:
                f.write(data.encode("utf-8") if isinstance(data, str) else data)
                f.flush()
                os.fsync(f.fileno())
        os.replace(tmp, path)
    except OSError as e:
        raise OutputError(option, path, write_reason(e)) from None
    finally:  # an interruption or a failed writer leaves no temporary file behind
        if tmp.exists():
            tmp.unlink()
    return path


#: Figure file suffixes matplotlib writes (checked against matplotlib in the tests).
FIGURE_SUFFIXES = (".png", ".pdf", ".svg", ".svgz", ".eps", ".ps", ".jpg", ".jpeg", ".tif",
                   ".tiff", ".webp")
#: Telemetry file suffixes (apps/telemetry_files.FORMATS).
TELEMETRY_SUFFIXES = (".csv", ".parquet")


def check_output(option, path, directory=False, suffixes=None):
    """Refuse, before the work, an output path that cannot be written.

    Parameters
    ----------
    option : str
        The option naming the path (``--json``), for the message.
    path : path-like or None
        The path; None (option not given) and ``-`` (stdout) pass.
    directory : bool
        The path is a directory to be created if needed (``--plots DIR``): its
        nearest existing ancestor must be a writable directory.
    suffixes : sequence of str, optional
        The suffixes accepted (``.csv``, ``.parquet``).

    Raises
    ------
    OutputError
        Naming the option, the path and why.
    """
    if path is None or str(path) == "-":
        return
    path = Path(path)
    if directory:
        probe = path
        while not probe.exists():
            if probe.parent == probe:
                break
            probe = probe.parent
        if not probe.is_dir():
            raise OutputError(option, path, f"{probe} is not a directory")
        if not os.access(probe, os.W_OK | os.X_OK):
            raise OutputError(option, path, f"{probe}: permission denied")
        return
    if suffixes is not None and path.suffix.lower() not in suffixes:
        raise OutputError(option, path, f"unknown suffix {path.suffix or '(none)'!r}; "
                          f"use {' or '.join(suffixes)}")
    parent = path.parent
    if path.is_dir():
        raise OutputError(option, path, "it is a directory")
    if not parent.exists():
        raise OutputError(option, path, "directory does not exist")
    if not parent.is_dir():
        raise OutputError(option, path, f"{parent} is not a directory")
    if not os.access(parent, os.W_OK | os.X_OK):
        raise OutputError(option, path, "permission denied")


def cap_workers(requested, runs, cores=None):
    """Worker processes to start for ``runs`` jobs, and a note when fewer than asked.

    Never more than the runs (an idle process is only a cost), and never more
    than the cores (more processes than cores only share them); the note
    says so when a request is lowered.

    Parameters
    ----------
    requested : int or None
        The ``--workers`` asked for (None: one per core).
    runs : int
        Jobs to fly.
    cores : int, optional
        Cores available (default ``os.cpu_count()``).

    Returns
    -------
    (int, str or None)
    """
    cores = cores or os.cpu_count() or 1
    want = cores if requested is None else int(requested)
    n = max(1, min(want, cores, runs))
    if requested is None or n == want:
        return n, None
    why = [f"{runs} run{'s' if runs != 1 else ''}" if n == runs else None,
           f"{cores} core{'s' if cores != 1 else ''}" if n == cores and want > cores else None]
    return n, (f"--workers {want}: starting {n} worker process{'es' if n > 1 else ''} "
               f"({' and '.join(w for w in why if w)})")


class Interrupted(Exception):
    """Work stopped by Ctrl-C or SIGTERM; the message says what was written."""
