"""Output files: checked before the work, written whole or not at all.

Every file a command writes (telemetry, JSON, figures, campaign records) goes
through :func:`write_atomic`. A regular file, or a path that does not exist
yet, is written under a temporary name in its own directory and renamed over
the target (``os.replace``), so that an interruption or a full disk leaves
the old file or the new one, never half of one. A symbolic link is followed:
the file it points to is replaced, the link stays. Anything else (a FIFO, a
device such as ``/dev/null``, ``/dev/stdout``, a pipe from the shell's
process substitution ``>(...)``) is written directly, in place: renaming over
it would replace the node itself. Such a direct write cannot be atomic;
:func:`torn_writes` lists the ones an interruption cut short.

:func:`check_output` refuses, before any mission is flown, a path that could
not be written, and :func:`check_distinct` two outputs (or an output and an
input) that are one file; :class:`OutputError` names the option and the path
in one line. :func:`cap_workers` is the one rule for how many worker
processes a command starts.
"""

import errno
import os
import re
import shutil
import signal
import stat
import sys
import tempfile
from pathlib import Path


class OutputError(Exception):
    """An output path that cannot be written, named by its option (one line).

    ``option`` is the command-line option that gave the path (``--json``;
    None when no option did), ``path`` the path and ``reason`` why, in words
    (:func:`write_reason`).
    """

    def __init__(self, option, path, reason):
        self.option, self.path, self.reason = option, str(path), reason
        super().__init__(f"{option}: cannot write {path}: {reason}" if option
                         else f"cannot write {path}: {reason}")


def write_reason(e: OSError) -> str:
    """A short reason for a failed write, in words rather than errno text.

    ``e`` is the error the write raised.
    """
    return {errno.ENOENT: "directory does not exist", errno.EACCES: "permission denied",
            errno.EPERM: "permission denied", errno.EROFS: "read-only file system",
            errno.ENOSPC: "no space left on the device", errno.EDQUOT: "disk quota exceeded",
            errno.EISDIR: "it is a directory", errno.ENOTDIR: "a parent is not a directory",
            errno.ENAMETOOLONG: "name too long", errno.EPIPE: "the reader closed the pipe",
            errno.EBADF: "the descriptor is not open for writing",
            errno.ENXIO: "no reader on the FIFO or device"}.get(e.errno,
                                                                 e.strerror or str(e))


def _temporary(path: Path) -> Path:
    # Same directory (so that the rename is atomic), same suffix (writers pick the format
    # by it: .csv/.parquet, .png), hidden, and unique to this process.
    return path.with_name(f".{path.stem}.tmp{os.getpid()}{path.suffix}")


#: The signals that end a command as Ctrl-C does (exit 130): SIGHUP comes from a closed
#: terminal or a dropped ssh session.
ENDING_SIGNALS = tuple(getattr(signal, n) for n in ("SIGINT", "SIGTERM", "SIGHUP")
                       if hasattr(signal, n))
#: Paths that name an open file descriptor of this process rather than a file.
_FD_PATH = re.compile(r"^/(?:dev/fd|proc/self/fd|proc/thread-self/fd)/([0-9]+)$")
_STD_PATHS = {"/dev/stdin": 0, "/dev/stdout": 1, "/dev/stderr": 2}
#: Symbolic links followed at most (the kernel's own limit is 40).
_MAX_LINKS = 40


def descriptor_of(path):
    """The file descriptor a path names (``/dev/stdout``, ``/dev/fd/63``), or None.

    ``path`` is any path (str or path-like).

    Such a path reaches a descriptor this process already holds (the shell's
    redirection or process substitution): writing goes through that
    descriptor, at its offset, rather than by reopening (and truncating) what
    it points to. Symbolic links leading to such a path count too.
    """
    text = os.path.abspath(os.fspath(path))
    for _ in range(_MAX_LINKS):
        if text in _STD_PATHS:
            return _STD_PATHS[text]
        m = _FD_PATH.match(text) or re.match(rf"^/proc/{os.getpid()}/fd/([0-9]+)$", text)
        if m:
            return int(m.group(1))
        try:
            link = os.readlink(text)
        except (OSError, ValueError):
            return None
        text = os.path.normpath(os.path.join(os.path.dirname(text), link))
    return None


def _kind(path: Path):
    """("new" | "regular" | "directory" | "special", the real path to write)."""
    try:
        st = os.stat(path)  # follows symbolic links
    except FileNotFoundError:
        # A new file, or a link to one yet to exist: it is made where the link points.
        return "new", Path(os.path.realpath(path))
    if stat.S_ISREG(st.st_mode):
        return "regular", Path(os.path.realpath(path))
    if stat.S_ISDIR(st.st_mode):
        return "directory", Path(path)
    return "special", Path(path)


#: Direct writes (not to a regular file) that an interruption or an error cut short.
_torn = []
#: Every file written whole by this process's command so far (:func:`written_files`).
_completed = []


def written_files() -> list:
    """The outputs written whole so far, in order.

    A message after an interruption names them; :func:`forget_written`
    starts the list again for a new command.
    """
    return list(_completed)


def forget_written():
    """Start :func:`written_files` again (a new command in this process)."""
    _completed.clear()


def torn_writes() -> list:
    """Paths written in place (a FIFO, a device, a descriptor) and cut short.

    A regular file is replaced whole or not at all; a direct write is not, so
    a message after an interruption says "nothing half-written" only when
    this list is empty.
    """
    return list(_torn)


def flush_console():
    """Flush ``sys.stdout`` and ``sys.stderr``, passing over a closed or missing one."""
    for stream in (sys.stdout, sys.stderr):
        try:
            if stream is not None:
                stream.flush()
        except (OSError, ValueError):
            pass


def _write_fd(fd: int, data: bytes):
    if fd in (1, 2):  # what this process printed goes first
        flush_console()
    view = memoryview(data)
    while view:
        view = view[os.write(fd, view):]


def _write_direct(path: Path, data: bytes):
    fd = descriptor_of(path)
    if fd is not None:
        _write_fd(fd, data)
        return
    from allsky.config.toml_io import open_fifo_waiting

    # A FIFO or a device: opened as it is, never replaced; a FIFO with no reader is
    # reported after a second, then waited for.
    with open_fifo_waiting(path, "wb", "output") as f:
        f.write(data)


def write_atomic(path, data=None, writer=None, option=None) -> Path:
    """Write ``path`` whole or not at all; a FIFO, a device or a descriptor directly.

    Parameters
    ----------
    path : path-like
        The file to write. A symbolic link is followed (the file it points
        to is replaced). A FIFO, a device or a descriptor path
        (``/dev/stdout``, ``/dev/fd/N``) is written in place.
    data : str or bytes, optional
        The content (text is written as UTF-8).
    writer : callable, optional
        ``writer(temporary_path)`` writes the content itself (figures,
        Parquet); used instead of ``data``. For a direct write it writes a
        temporary file, which is then copied to the target.
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
    kind, real = _kind(path) if descriptor_of(path) is None else ("special", path)
    if kind == "directory":
        raise OutputError(option, path, "it is a directory")
    if kind == "special":
        _write_special(path, data, writer, option)
        _completed.append(str(path))
        return path
    tmp = _temporary(real)
    try:
        if writer is not None:
            writer(tmp)
        else:
            with tmp.open("wb") as f:
                f.write(data.encode("utf-8") if isinstance(data, str) else data)
                f.flush()
                os.fsync(f.fileno())
        os.replace(tmp, real)
        _completed.append(str(path))
    except OSError as e:
        raise OutputError(option, path, write_reason(e)) from None
    finally:  # an interruption or a failed writer leaves no temporary file behind
        if tmp.exists():
            tmp.unlink()
    return path


def _write_special(path: Path, data, writer, option):
    """Write a FIFO, a device or a descriptor in place (:func:`write_atomic`)."""
    scratch = None
    try:
        if writer is not None:  # the writer makes a file; its bytes go to the target
            scratch = Path(tempfile.mkdtemp(prefix="allsky-out-"))
            made = scratch / f"out{path.suffix}"
            writer(made)
            data = made.read_bytes()
        elif isinstance(data, str):
            data = data.encode("utf-8")
        _torn.append(str(path))  # until the last byte is out: an interruption tears it
        _write_direct(path, data)
        _torn.remove(str(path))
    except OSError as e:
        raise OutputError(option, path, write_reason(e)) from None
    finally:
        if scratch is not None:
            shutil.rmtree(scratch, ignore_errors=True)


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
    if "\0" in str(path):  # no file system takes one
        raise OutputError(option, path, "a NUL character in the path")
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
    if suffixes is not None and path.suffix.lower() not in suffixes and not is_null_device(path):
        raise OutputError(option, path, f"unknown suffix {path.suffix or '(none)'!r}; "
                          f"use {' or '.join(suffixes)}")
    fd = descriptor_of(path)
    if fd is not None:  # /dev/stdout, /dev/fd/N: a descriptor open for writing
        try:
            import fcntl

            mode = fcntl.fcntl(fd, fcntl.F_GETFL) & os.O_ACCMODE
        except (ImportError, OSError):
            raise OutputError(option, path, "the descriptor is not open") from None
        if mode == os.O_RDONLY:
            raise OutputError(option, path, "the descriptor is open for reading only")
        return
    kind, real = _kind(path)
    if kind == "directory":
        raise OutputError(option, path, "it is a directory")
    if kind == "special":  # written in place: the node itself must be writable
        if not os.access(path, os.W_OK):
            raise OutputError(option, path, "permission denied")
        return
    parent = real.parent  # a new file or a replaced one: made in the real directory
    if not parent.exists():
        raise OutputError(option, path, "directory does not exist")
    if not parent.is_dir():
        raise OutputError(option, path, f"{parent} is not a directory")
    if not os.access(parent, os.W_OK | os.X_OK):
        raise OutputError(option, path, "permission denied")


def is_null_device(path) -> bool:
    """Whether ``path`` is the null device (it takes any output, of any suffix)."""
    try:
        st, null = os.stat(path), os.stat(os.devnull)
    except (OSError, ValueError):
        return False
    return stat.S_ISCHR(st.st_mode) and st.st_rdev == null.st_rdev


def _identity(path: Path):
    """What makes two paths one file: (device, inode) when it exists, else its real path."""
    fd = descriptor_of(path)
    try:
        st = os.fstat(fd) if fd is not None else os.stat(path)
    except (OSError, ValueError):
        try:
            return ("path", os.path.realpath(path))
        except ValueError:  # a NUL in the path: no file, the reader says so
            return ("path", str(path))
    if stat.S_ISCHR(st.st_mode) and os.path.exists(os.devnull) and (
            st.st_rdev == os.stat(os.devnull).st_rdev):
        return None  # the null device takes any number of outputs
    return ("node", st.st_dev, st.st_ino)


def check_distinct(outputs, inputs=()):
    """Refuse two outputs that are one file, or an output that is an input.

    Parameters
    ----------
    outputs : sequence of (option, path, names)
        Each output given (None paths are skipped); ``names`` is None for a
        file, or the file names a directory output writes into its directory
        (``--plots DIR``), which must then not be another output.
    inputs : sequence of (option, path)
        Files the command reads: no output may replace one.

    Raises
    ------
    OutputError
        Naming both options and the path.
    """
    stdout = _identity(Path("/dev/stdout")) if _open(1) else ("stdout",)
    seen = {}  # identity -> option
    given = [(o, p, names) for o, p, names in outputs if p is not None]

    def claim(option, path, identity):
        if identity is None:
            return
        other = seen.get(identity)
        if other is not None and other != option:
            raise OutputError(option, path, f"{other} writes the same file; give each "
                              "output its own path")
        if other is None and identity in inputs_seen:
            raise OutputError(option, path, f"it is the {inputs_seen[identity]} this command "
                              "reads; write the output elsewhere")
        seen[identity] = option

    inputs_seen = {}
    for option, path in inputs:
        if path is not None and str(path) != "-":
            ident = _identity(Path(path))
            if ident is not None:
                inputs_seen.setdefault(ident, option)
    for option, path, names in given:
        if str(path) == "-":
            claim(option, path, stdout)
            continue
        claim(option, path, _identity(Path(path)))
        for name in names or ():
            claim(option, Path(path) / name, _identity(Path(path) / name))


def _open(fd) -> bool:
    try:
        os.fstat(fd)
    except OSError:
        return False
    return True


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
