"""stdout and stderr that no closed pipe, closed descriptor or encoding can stop.

:class:`ConsoleStream` wraps ``sys.stdout`` or ``sys.stderr`` for the length
of a command (:func:`guarded`). A write that fails because the reader went
away (``allsky ... | head -1``), the descriptor is closed (``allsky run >&-``)
or the device is full is not an error of the command: the stream notes the
loss, points its descriptor at the null device (so that nothing waits in its
buffer) and takes every later write without a word, so the command goes on
and writes every file it was asked for; :func:`allsky.apps.cli.main` then
ends with the exit code that says stdout was lost. Text the console's
encoding cannot show (``PYTHONIOENCODING=ascii``, a C locale) is written in
ASCII (:func:`ascii_text`: ``±`` as ``+/-``, ``″`` as ``"``), never an error.
"""

import contextlib
import errno
import os
import sys
import unicodedata
import warnings

#: Characters the reports use, and their ASCII forms.
ASCII_FORMS = {"±": "+/-", "″": '"', "′": "'", "°": " deg", "→": "->", "←": "<-",
               "−": "-", "–": "-", "—": "--", "…": "...", "×": "x", "≤": "<=", "≥": ">=",
               "≈": "~", "µ": "u", "σ": "sigma", "²": "^2", "³": "^3", "√": "sqrt ",
               "▽": "v", "△": "^", "·": ".", "‖": "||", "Δ": "d", "ω": "w", "⁻¹": "^-1",
               "¹": "^1", "█": "#", "▏": "|", "▎": "|", "▍": "|", "▌": "|", "▋": "|",
               "▊": "|", "▉": "|"}


def ascii_text(text: str, encoding: str = "ascii") -> str:
    """``text`` as ``encoding`` can show it: symbols spelled out, accents dropped."""
    out = []
    for ch in text:
        try:
            ch.encode(encoding)
            out.append(ch)
            continue
        except (UnicodeEncodeError, LookupError):
            pass
        form = ASCII_FORMS.get(ch)
        if form is None:
            base = unicodedata.normalize("NFKD", ch).encode("ascii", "ignore").decode()
            form = base or "?"
        out.append(form)
    return "".join(out)


class ConsoleStream:
    """A text stream that survives the loss of its descriptor and any encoding.

    Parameters
    ----------
    stream : text stream or None
        ``sys.stdout`` or ``sys.stderr`` (None when Python started without it).
    fd : int
        Its descriptor (1 or 2).

    Attributes
    ----------
    lost : int or None
        The errno that lost the stream (``EPIPE``: the reader went away;
        ``EBADF``: no descriptor), None while it works.
    dropped : bool
        Something written to it after the loss (or lost with it).
    """

    def __init__(self, stream, fd: int):
        self._stream, self.fd = stream, fd
        self.lost = errno.EBADF if stream is None else None
        self.dropped = False

    def _lose(self, e: OSError):
        self.lost, self.dropped = e.errno or errno.EIO, True
        try:  # what waits in the buffer goes to the null device, now and at exit
            null = os.open(os.devnull, os.O_WRONLY)
            os.dup2(null, self.fd)
            os.close(null)
            self._stream.flush()
        except (OSError, ValueError):
            pass

    def write(self, text: str) -> int:
        """Write ``text``; after a loss, take it without a word (``dropped`` says so)."""
        if self.lost is not None:
            self.dropped = self.dropped or bool(text)
            return len(text)
        try:
            try:
                return self._stream.write(text)
            except UnicodeEncodeError:
                return self._stream.write(ascii_text(text, self.encoding or "ascii"))
        except (OSError, ValueError) as e:  # ValueError: the stream was closed
            self._lose(e if isinstance(e, OSError) else OSError(errno.EBADF, str(e)))
            return len(text)

    def flush(self):
        """Flush; a loss is noted, not raised."""
        if self.lost is None:
            try:
                self._stream.flush()
            except (OSError, ValueError) as e:
                self._lose(e if isinstance(e, OSError) else OSError(errno.EBADF, str(e)))

    def isatty(self) -> bool:
        """Whether the stream is a terminal (False once lost)."""
        if self.lost is not None:
            return False
        try:
            return self._stream.isatty()
        except (OSError, ValueError):
            return False

    def fileno(self) -> int:
        """The descriptor."""
        return self.fd

    @property
    def encoding(self):
        """The underlying stream's encoding (UTF-8 when there is none)."""
        return getattr(self._stream, "encoding", None) or "utf-8"

    def __getattr__(self, name):
        if self._stream is None:
            raise AttributeError(name)
        return getattr(self._stream, name)


def _descriptors_open():
    """Give descriptors 0-2 the null device where they are closed; return those that were.

    A command started with stdout closed (``>&-``) would otherwise hand
    descriptor 1 to the next file it opens, and its report would land there.
    """
    closed = []
    for fd in (0, 1, 2):
        try:
            os.fstat(fd)
        except OSError:
            null = os.open(os.devnull, os.O_RDONLY if fd == 0 else os.O_WRONLY)
            if null != fd:
                os.dup2(null, fd)
                os.close(null)
            closed.append(fd)
    return closed


@contextlib.contextmanager
def guarded(on_lost_interrupt=None):
    """``sys.stdout`` and ``sys.stderr`` as :class:`ConsoleStream` inside the block.

    Yields ``(stdout, stderr)``; a descriptor closed when the command started
    counts as lost from the start. A command started without stdin reads an
    empty one (the null device). An exception Python can only ignore (raised
    in a callback from compiled code) is one line, not a traceback; a
    KeyboardInterrupt lost that way calls ``on_lost_interrupt``, if given,
    with no arguments: it delivers it again.
    """
    closed = _descriptors_open()
    old_in, old_out, old_err = sys.stdin, sys.stdout, sys.stderr
    out = ConsoleStream(None if 1 in closed else old_out, 1)
    err = ConsoleStream(None if 2 in closed else old_err, 2)
    sys.stdout, sys.stderr = out, err
    no_input = None
    if old_in is None:  # started with stdin closed: an empty input, never a prompt
        no_input = sys.stdin = open(os.devnull, encoding="utf-8")  # noqa: SIM115
    old_show, old_hook = warnings.showwarning, sys.unraisablehook
    warnings.showwarning = _one_line_warning

    def unraisable(args):
        if isinstance(args.exc_value, KeyboardInterrupt):
            if on_lost_interrupt is not None:
                on_lost_interrupt()
            return
        where = f" in {args.object!r}" if args.object is not None else ""
        print(f"allsky: warning: ignored{where}: {type(args.exc_value).__name__}: "
              f"{' '.join(str(args.exc_value).split())[:200]}", file=sys.stderr)

    sys.unraisablehook = unraisable
    try:
        yield out, err
    finally:
        warnings.showwarning, sys.unraisablehook = old_show, old_hook
        out.flush()
        err.flush()
        sys.stdin, sys.stdout, sys.stderr = old_in, old_out, old_err
        if no_input is not None:
            no_input.close()


def _one_line_warning(message, category, filename, lineno, file=None, line=None):
    """A warning as one line on stderr: ``allsky: warning: ...`` (no source line)."""
    text = " ".join(str(message).split())
    text = text[len("allsky: "):] if text.startswith("allsky: ") else (
        f"{category.__name__}: {text}")
    print(f"allsky: warning: {text}", file=file or sys.stderr)
