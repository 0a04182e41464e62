"""Local worker processes, one job each at a time; a dead one is replaced.

:class:`WorkerPool` flies jobs on a few worker processes, each holding one
job at a time, so that the parent always knows which job each worker has.
A worker that dies in the middle of a job (SIGKILL, the kernel's
out-of-memory killer, a crash in compiled code) is replaced by a new one and
its job is flown again, once: a job whose worker dies twice is handed back as
:class:`Died`, and the campaign goes on. The results are those of an
undisturbed campaign, because every job is a pure function of its input.

Jobs are drawn from an iterator only when a worker is free, so a campaign of
any size holds no list of its jobs. Ctrl-C (or SIGTERM, which the command
line turns into one) stops the handing out: :meth:`WorkerPool.finish` waits
for the jobs under way, which the workers finish (they ignore the signal),
and a second Ctrl-C during that wait ends them at once. The pool uses
:mod:`multiprocessing` pipes directly rather than :mod:`concurrent.futures`,
whose process pool turns one dead worker into the loss of every job in flight
and, on Python 3.11, can print an ``InvalidStateError`` traceback from its
manager thread when a campaign is interrupted.
"""

import os
import signal
import sys
import threading
import time
from multiprocessing import connection, get_context
from typing import NamedTuple


class Died(NamedTuple):
    """The result of a job whose worker died each time it flew it."""

    exit_codes: tuple  #: each dead worker's exit code (-N: killed by signal N)

    def reason(self) -> str:
        """In words: "its worker process died twice (SIGKILL, SIGKILL)"."""
        how = []
        for code in self.exit_codes:
            try:
                how.append(signal.Signals(-code).name if code < 0 else f"exit code {code}")
            except ValueError:
                how.append(f"signal {-code}")
        times = {1: "once", 2: "twice"}.get(len(how), f"{len(how)} times")
        return f"its worker process died {times} ({', '.join(how)})"


#: Times a job is flown on a fresh worker after its worker died: once.
RETRIES = 1
#: Workers that may die in a row before a job reached them (their start-up
#: failing: an environment that cannot run a mission) before the pool gives up.
MAX_DEATHS_AT_START = 3
#: [s] Longest an idle worker asked to stop is waited for before it is terminated.
END_WAIT_S = 2.0
#: [s] How often a worker checks that its parent is still there (where the
#: kernel cannot be asked to signal it, or was asked too late).
PARENT_CHECK_S = 0.5
#: prctl(2) option: the signal the kernel sends this process when its parent dies.
_PR_SET_PDEATHSIG = 1


class PoolError(Exception):
    """The worker processes cannot run at all (each died before its first job)."""


def worker_process_setup(parent_pid: int):
    """Make a worker process quiet on Ctrl-C and end it when its parent goes.

    Ctrl-C (sent to the whole terminal process group) and SIGTERM are the
    parent's to handle: it stops handing out jobs, lets the workers finish
    the ones under way and saves them, so the worker ignores SIGINT and takes
    SIGTERM's default action (a forked worker would otherwise inherit the
    parent's handler). If the parent is killed (even by SIGKILL, which it
    cannot handle), the worker must not fly on for minutes: on Linux the
    kernel sends it SIGTERM (``prctl(PR_SET_PDEATHSIG)``); everywhere a daemon
    thread checks every :data:`PARENT_CHECK_S` that the parent is still
    ``parent_pid``.
    """
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    if hasattr(signal, "SIGHUP"):  # a closed terminal hangs up the whole group: the parent's
        signal.signal(signal.SIGHUP, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    if sys.platform.startswith("linux"):
        try:
            import ctypes

            libc = ctypes.CDLL(None, use_errno=True)
            libc.prctl(_PR_SET_PDEATHSIG, int(signal.SIGTERM), 0, 0, 0)
        except (OSError, AttributeError):  # no prctl: the thread below suffices
            pass

    def watch_parent():
        while os.getppid() == parent_pid:
            time.sleep(PARENT_CHECK_S)
        os.kill(os.getpid(), signal.SIGTERM)

    if os.getppid() != parent_pid:  # the parent went before the kernel was asked
        os.kill(os.getpid(), signal.SIGTERM)
    threading.Thread(target=watch_parent, name="allsky-parent-watch", daemon=True).start()
    _unblock()


#: The signals a worker is started with blocked (:class:`_Worker`), until it has set its own
#: handlers: a Ctrl-C at the instant of the fork reaches no handler of the parent's.
_HELD = {signal.SIGINT, signal.SIGTERM} | (
    {signal.SIGHUP} if hasattr(signal, "SIGHUP") else set())


def _unblock():
    if hasattr(signal, "pthread_sigmask"):
        signal.pthread_sigmask(signal.SIG_UNBLOCK, _HELD)


#: A worker's messages: it took the job (so a death from now on is the job's), its result,
#: the exception it raised, and that it starts (True) or ends (False) compiling the frame
#: loop (:data:`allsky.compiles.ON_COMPILE`).
_TOOK, _DONE, _FAILED, _COMPILING = 0, 1, 2, 3


def _serve(conn, parent_pid, fn, initializer, initargs):
    """A worker's life: set up, then answer each job (:data:`_TOOK`, then its result)."""
    worker_process_setup(parent_pid)
    _tell_compiles(conn)
    broken = None
    if initializer is not None:
        try:
            initializer(*initargs)
        except Exception as e:  # noqa: BLE001 - the answer to every job, raised there
            broken = e
    while True:
        try:
            job = conn.recv()
        except (EOFError, OSError):  # the parent is gone
            return
        if job is None:
            return
        if broken is not None:
            reply = (_FAILED, broken)
        else:
            try:
                conn.send((_TOOK, None))
            except (OSError, ValueError):  # the parent is gone
                return
            try:
                reply = (_DONE, fn(job))
            except Exception as e:  # noqa: BLE001 - handed to the parent, raised there
                reply = (_FAILED, e)
        try:
            conn.send(reply)
        except (OSError, ValueError):
            return


def _tell_compiles(conn):
    """Make this worker tell its parent when it compiles the frame loop, and when done."""
    from allsky import compiles

    def tell(on):
        try:
            conn.send((_COMPILING, bool(on)))
        except (OSError, ValueError):  # the parent is gone: its watch ends this worker
            pass

    compiles.ON_COMPILE[:] = [tell]


class _Worker:
    def __init__(self, ctx, fn, initializer, initargs):
        self.conn, child = ctx.Pipe()
        self.process = ctx.Process(target=_serve, daemon=True, name="allsky-worker",
                                   args=(child, os.getpid(), fn, initializer, initargs))
        mask = hasattr(signal, "pthread_sigmask") and (
            threading.current_thread() is threading.main_thread())
        old = signal.pthread_sigmask(signal.SIG_BLOCK, _HELD) if mask else None
        try:
            self.process.start()
        finally:
            if mask:
                signal.pthread_sigmask(signal.SIG_SETMASK, old)
            child.close()
        self.key = self.job = None
        self.took = False  # the worker said it took its job (a death then is the job's)
        self.compiling = False  # it said it is compiling the frame loop (or waits for it)

    def give(self, key, job):
        self.key, self.job, self.took = key, job, False
        self.conn.send(job)

    def end(self, at_once=False):
        try:
            if at_once:
                self.process.terminate()
            else:
                self.conn.send(None)
        except (OSError, ValueError):
            self.process.terminate()
        self.process.join(timeout=END_WAIT_S)
        if self.process.is_alive():  # still in its start-up (a compile): no need to wait
            self.process.terminate()
            self.process.join()
        self.conn.close()


class WorkerPool:
    """``fn(job)`` on ``workers`` processes, one job each, dead workers replaced.

    Parameters
    ----------
    fn : callable
        Module-level function of one job (it crosses to the workers).
    workers : int
        Worker processes.
    initializer, initargs : optional
        Called as ``initializer(*initargs)`` once in each worker, before its
        first job (replacement workers too).

    Use :meth:`results` over ``(key, job)`` pairs, then :meth:`close`
    (or :meth:`finish` after a Ctrl-C).
    """

    def __init__(self, fn, workers, initializer=None, initargs=()):
        self._ctx = get_context("fork" if sys.platform.startswith("linux") else None)
        self._fn, self._initializer, self._initargs = fn, initializer, initargs
        self._size = max(1, int(workers))
        self._idle, self._busy = [], {}  # busy: connection -> worker
        self._queue = []  # (key, job) to fly again, before any new job
        self._deaths = {}  # key -> exit codes of the workers that died flying it
        self._starts_lost = 0
        self._jobs = iter(())
        self.replaced = 0  #: workers that died and were replaced

    def _start(self):
        self._idle.append(_Worker(self._ctx, self._fn, self._initializer, self._initargs))

    def _next(self):
        if self._queue:
            return self._queue.pop(0)
        return next(self._jobs, None)

    def _hand_out(self):
        while self._idle:
            item = self._next()
            if item is None:
                return
            w = self._idle.pop()
            try:
                w.give(*item)
            except (OSError, ValueError):  # it died before taking the job (which is requeued)
                self._lost(w, job_started=False)
                continue
            self._busy[w.conn] = w

    def _lost(self, w, job_started=True):
        """Worker ``w`` died: replace it; its job goes again once, or comes back Died."""
        self._busy.pop(w.conn, None)
        w.process.join()
        w.conn.close()
        self.replaced += 1
        died = None
        if job_started and w.key is not None:
            self._starts_lost = 0
            codes = self._deaths[w.key] = (*self._deaths.get(w.key, ()), w.process.exitcode)
            if len(codes) > RETRIES:
                died = (w.key, Died(codes))
            else:
                self._queue.insert(0, (w.key, w.job))
        else:
            if w.key is not None:  # a job it never took goes to the next worker as it is
                self._queue.insert(0, (w.key, w.job))
            self._starts_lost += 1
            if self._starts_lost >= MAX_DEATHS_AT_START:
                raise PoolError(f"{self._starts_lost} worker processes died before their "
                                f"first job (exit code {w.process.exitcode})")
        self._start()
        return died

    def _collect(self, ready):
        """Results of the ``ready`` connections and sentinels: [(key, result)]."""
        out = []
        for w in list(self._busy.values()):
            if w.conn not in ready and w.process.sentinel not in ready:
                continue
            message = None
            try:
                while w.conn.poll():
                    message = w.conn.recv()
                    if message[0] == _TOOK:
                        w.took = True
                    elif message[0] == _COMPILING:
                        w.compiling = message[1]
                    else:
                        break
                    message = None
            except (EOFError, OSError):
                message = None
            if message is None:
                if w.process.is_alive():  # it took the job and is flying it
                    continue
                # No answer: the worker died, with its job if it had taken it.
                died = self._lost(w, job_started=w.took)
                if died is not None:
                    out.append(died)
                continue
            kind, result = message
            key = w.key
            del self._busy[w.conn]
            w.key = w.job = None
            self._idle.append(w)
            self._deaths.pop(key, None)
            if kind == _FAILED:
                raise result
            self._starts_lost = 0
            out.append((key, result))
        for w in list(self._idle):  # an idle worker that died (before its first job)
            if w.process.sentinel in ready or not w.process.is_alive():
                self._idle.remove(w)
                self._lost(w, job_started=False)
        return out

    def results(self, jobs):
        """Fly ``(key, job)`` pairs; yield ``(key, result)`` as each ends.

        ``result`` is a :class:`Died` for a job whose worker died twice. An
        exception raised by ``fn`` is raised here.

        Parameters
        ----------
        jobs : iterable of (key, job)
            Drawn one at a time, as a worker comes free; ``key`` names the
            job in the results (each key once), ``job`` is ``fn``'s argument.
        """
        self._jobs = iter(jobs)
        while len(self._idle) + len(self._busy) < self._size:
            self._start()
        while True:
            self._hand_out()
            if not self._busy:
                return
            waits = [*self._busy, *(w.process.sentinel for w in self._busy.values()),
                     *(w.process.sentinel for w in self._idle)]
            done = self._collect(connection.wait(waits))
            self._hand_out()  # the free workers fly on while the caller records these
            yield from done

    def finish(self) -> list:
        """After a Ctrl-C: hand out nothing more; the jobs under way, finished.

        Waits for the workers' current jobs and returns their ``(key,
        result)``. A job is under way once its worker took it and while it is
        not compiling: a worker still starting (its initializer, the job not
        yet taken) or compiling the frame loop (a minute on an empty cache, or
        waiting for another process's compile) is ended at once, and its job
        with it. A second Ctrl-C (or SIGTERM) during the wait ends the
        workers at once and returns what had finished.
        """
        self._jobs, self._queue = iter(()), []
        out = []

        def keep(pairs):
            out.extend((key, result) for key, result in pairs if not isinstance(result, Died))
            self._queue = []  # a job whose worker died is not flown again now

        try:
            while self._busy:
                keep(self._collect(set(self._busy)))  # what they said so far (no wait)
                for w in [w for w in self._busy.values() if w.compiling or not w.took]:
                    del self._busy[w.conn]
                    w.end(at_once=True)
                if not self._busy:
                    break
                waits = [*self._busy, *(w.process.sentinel for w in self._busy.values())]
                keep(self._collect(connection.wait(waits)))
        except KeyboardInterrupt:
            self.close(at_once=True)
        return out

    def close(self, at_once=False):
        """End the workers (``at_once``: all terminated, jobs under way lost).

        Workers still on a job are terminated in any case; idle ones are
        asked to stop.
        """
        idle, busy = self._idle, list(self._busy.values())
        self._idle, self._busy = [], {}
        for w in busy:
            w.end(at_once=True)
        for w in idle:
            w.end(at_once=at_once)
