"""``allsky serve``: fly a mission live in the browser, command it, fly it again.

The mission flies in a thread of its own (:class:`Flight`): in slices of
:data:`SLICE_WALL_S` of wall time, each as many frames as the speed asks
for, paced to the wall clock. At each slice's frame boundary it applies
the commands the page sent (:class:`allsky.sim.commands.Station`: each a
``ground_command`` entry of the journal, at that boundary's mission time)
and hands the new telemetry rows, journal entries and page state to the
server. The speed only chooses how many frames a slice holds; the frame
loop pauses and resumes bit for bit, so what is flown never depends on it
nor on the clients: ``allsky run --commands`` flies the saved session again
exactly.

The server (:class:`Server`, aiohttp in a thread of its own) serves one
page and one WebSocket, both behind the session's random token (403
without it), the WebSocket's Origin checked, bound to 127.0.0.1 unless
``--allow-remote``. Each client gets the journal whole and the telemetry
decimated to what it takes: an update waits for the client's
acknowledgement of the one before, and holds at most :data:`ROWS_PER_UPDATE`
rows of what came meanwhile, the newest always among them. A client that
connects late, or again, gets the session so far: the whole journal and
the telemetry decimated to :data:`CATCH_UP_ROWS`. Losing every client loses
nothing: the mission flies on (or waits, with ``--pause-when-alone``).

The page is the replay's (:mod:`allsky.apps.replay`) with the ground's
controls (``replay_page/ground.*``) and ``window.allsky.command``. Ending
the session (the page's end button, Ctrl-C, SIGTERM) writes what ``allsky
run`` writes, and with ``--save-commands`` the command log
(:func:`allsky.sim.commands.log_text`). docs/ground_control.md.
"""

import asyncio
import hmac
import ipaddress
import json
import math
import os
import queue
import re
import secrets
import shutil
import signal
import sys
import threading
import time

import numpy as np

from allsky.apps import replay
from allsky.sequencer.ground import SEQUENCER_COMMANDS
from allsky.sim import commands as ground_commands

#: [s] of wall time a slice of the flight lasts: the page's updates and a command's delay.
SLICE_WALL_S = 0.05
#: Most telemetry rows an update to a client holds (the rest of what came is left out).
ROWS_PER_UPDATE = 400
#: [s] shortest wall time between two updates to one client.
UPDATE_EVERY_S = 0.1
#: Most telemetry rows a client that connects gets of the session so far.
CATCH_UP_ROWS = 20000
#: [s] shortest wall time between two computations of the page's journal state.
PAGE_EVERY_S = 0.25
#: [s] behind the wall clock beyond which the flight stops trying to catch up.
LAG_S = 0.5
#: Speeds the page offers [x real time].
SPEEDS = (1, 2, 5, 10, 20, 50, 100, 200, 500, 1000)
#: What a live page cannot show exactly, beside the replay's notes.
LIVE_NOTE = ("Live: the telemetry reaches this page decimated to what it can take (the journal "
             "never is); the telemetry file the session writes has every row.")
#: The session's default speed [x real time].
DEFAULT_SPEED = 20.0


class ServeError(Exception):
    """A serve option that cannot be honoured (the host, the port); exit 2."""


def is_loopback(host) -> bool:
    """Whether ``host`` (a name or an address) is this machine's loopback."""
    if host.lower() == "localhost":
        return True
    try:
        return ipaddress.ip_address(host.strip("[]")).is_loopback
    except ValueError:
        return False


#: A Host header: a name, an IPv4 address or a bracketed IPv6 address, and a port. Nothing
#: else is taken (the Host is written into the page): no quote, no space, no markup.
_HOST = re.compile(r"^(?:[A-Za-z0-9](?:[A-Za-z0-9.-]{0,252})|\[[0-9A-Fa-f:.]{2,45}\])"
                   r"(?::[0-9]{1,5})?$")


def clean_host(value):
    """A Host header ``value``, lowercased, or None when it is not a plain host[:port]."""
    if not isinstance(value, str) or not _HOST.match(value):
        return None
    return value.lower()


def _one_line(text, secrets_=()) -> str:
    """``text`` on one line, at most 200 characters, each of ``secrets_`` masked."""
    for secret in secrets_:
        if secret:
            text = text.replace(secret, "(token)")
    text = re.sub(r"token=(?!\(token\))[A-Za-z0-9_-]*", "token=(token)", text)  # a cut one
    text = " ".join(text.split())
    return text if len(text) <= 200 else text[:197] + "..."


class _LogLine:
    """A logging handler writing each record as one line on stderr: no traceback, no token.

    aiohttp logs a malformed request (an overlong line, too many headers,
    Content-Length with Transfer-Encoding) with its traceback and the request
    line, token included; the session's log says what happened in one line.
    """

    def __init__(self, tokens):
        import logging

        self.tokens = tokens

        class Handler(logging.Handler):
            def emit(inner, record):
                try:
                    what = record.getMessage()
                    if record.exc_info and record.exc_info[1] is not None:
                        e = record.exc_info[1]
                        what += f": {type(e).__name__}: {e}"
                    print(f"allsky: serve: {_one_line(what, self.tokens)}", file=sys.stderr)
                except Exception:  # noqa: BLE001, S110 - a log line never ends the session
                    pass

        self.handler = Handler(logging.INFO)
        self.loggers = [logging.getLogger(n) for n in ("aiohttp", "asyncio")]
        self.before = [(lg.handlers[:], lg.propagate) for lg in self.loggers]

    def __enter__(self):
        for lg in self.loggers:
            lg.handlers = [self.handler]
            lg.propagate = False
        return self

    def __exit__(self, *exc):
        for lg, (handlers, propagate) in zip(self.loggers, self.before):
            lg.handlers, lg.propagate = handlers, propagate


def _rows(table, start, stop, budget):
    """Rows ``start:stop`` of ``table``, at most ``budget`` of them, the last always kept."""
    n = stop - start
    if n <= budget:
        return table[start:stop]
    keep = np.unique(np.round(np.linspace(start, stop - 1, budget)).astype(np.int64))
    return table[keep]


class Flight:
    """The mission, flown in a thread of its own and commanded at frame boundaries.

    Parameters
    ----------
    cfg : allsky.config.Scenario
        The scenario to fly.
    speed : float
        [x real time] the live speed at the start.
    publish : callable
        ``publish(update)``, called from the flight's thread with each
        boundary's update (new rows, journal entries, session, page state).
    reply : callable
        ``reply(token, entry, error)`` for each command taken from the queue.
    pause_when_alone : bool
        Stop the clock while no client watches.
    """

    def __init__(self, cfg, speed, publish, reply, pause_when_alone=False):
        from allsky.sim.mission import Mission

        self.cfg = cfg
        self.m = Mission(cfg, telemetry=True)
        self.station = ground_commands.Station(self.m)
        self.speed = float(speed)
        self.publish = publish
        self.reply = reply
        self.pause_when_alone = pause_when_alone
        self.commands = queue.Queue()
        #: commands taken off the queue that wait for the next boundary, in order
        self._waiting = []
        #: the frame at which a plan-changing command closed the boundary (None: open)
        self._closed_at = None
        self.clients = 0
        self.thread = threading.Thread(target=self._run, name="allsky-flight", daemon=True)
        self.done = threading.Event()
        self.error = None  #: an exception that ended the flight's thread
        self._rows = 0
        self._events = 0
        self._page_at = -math.inf
        self._stale = False  #: journal entries published since the page's state was made
        self._anchor = (time.monotonic(), 0.0)
        self._frame_s = float(cfg.mission.frame_s)
        self._wall_s, self._since = 0.0, None

    # -- the thread ----------------------------------------------------------------
    def start(self):
        """Start flying (after loading or compiling the frame loop)."""
        self.thread.start()

    def _run(self):
        try:
            from allsky.sim.warm_up import LOOPS, warm_up

            warm_up(LOOPS)  # both loops: an injected fault must not wait for a compile
            self._anchor = (time.monotonic(), self.m.now_s())
            ground_commands.fly(self.m, self._boundary, self._pause_at)
            self._publish(force=True)
        except BaseException as e:  # noqa: BLE001 - the main thread reports it
            self.error = e
        finally:
            self.done.set()

    def _pause_at(self, m):
        if self._closed_at is not None:  # commands wait: the next boundary, at once
            return m.now_s()
        return m.now_s() + max(self.speed * SLICE_WALL_S, self._frame_s)

    def _boundary(self, m, where):
        self._closed_at = None  # a new boundary: the commands waiting may act
        self._take()
        self._publish()
        if where == "finished" and self._closed_at is None:  # standing still: wait for one
            self._clock(False)
            self._take(block=True)
            self._publish()
            if not m.finished and self._closed_at is None:  # flown again: paced or held
                self._anchor = (time.monotonic(), m.now_s())
                self._wait()
            return True
        if self._closed_at is None:  # acting on a command takes no mission time: no pacing
            self._wait()  # before the first mode too: paced, paused or waiting for a client
        return True

    def _clock(self, flying):
        """Keep the wall time the flight has flown (paused, alone or finished: none)."""
        now = time.monotonic()
        if flying and self._since is None:
            self._since = now
        elif not flying and self._since is not None:
            self._wall_s += now - self._since
            self._since = None

    def wall_s(self) -> float:
        """[s] wall time the flight has flown so far (not paused, not waiting)."""
        return self._wall_s + (time.monotonic() - self._since if self._since is not None
                               else 0.0)

    def _alone(self):
        return self.pause_when_alone and self.clients == 0

    def _wait(self):
        """Pace the flight to the wall clock; hold it while paused (or alone)."""
        while True:
            if self._closed_at is not None:  # a command to act on: on to the next boundary
                return
            if self.station.paused or self._alone():
                self._take(block=True, timeout=0.2)
                self._publish()  # the page's state catches up with the commands taken
                self._anchor = (time.monotonic(), self.m.now_s())
                self._clock(False)
                continue
            self._clock(True)
            wall, t0 = self._anchor
            remaining = wall + (self.m.now_s() - t0) / self.speed - time.monotonic()
            if remaining <= 0.0:
                if remaining < -LAG_S:  # behind: go on from here, no burst to catch up
                    self._anchor = (time.monotonic(), self.m.now_s())
                return
            if self._take(block=True, timeout=remaining):
                self._publish()

    def _take(self, block=False, timeout=None) -> int:
        """Apply the commands waiting (with ``block``, the first as it comes).

        As a saved session's flight takes them (:meth:`allsky.sim.commands.Station.take`):
        after a command that changes the plan, the rest wait for the next
        boundary, where the flight has acted on it (at the same frame).
        """
        n, held = 0, []
        while True:
            if self._waiting:
                item = self._waiting.pop(0)
            else:
                try:
                    item = self.commands.get(block=block and n == 0 and self._closed_at is None,
                                             timeout=timeout)
                except queue.Empty:
                    break
            # Past a plan-changing command only the session's own clock commands act here.
            if self._closed_at is not None and item[0]["kind"] not in \
                    ground_commands.SESSION_CLOCK:
                held.append(item)
                continue
            n += 1
            self._apply(*item)
            if item[0]["kind"] in SEQUENCER_COMMANDS:
                self._closed_at = self.m.frame
        self._waiting = held + self._waiting
        return n

    def _apply(self, command, token):
        try:
            entry = self.station.apply(command)
        except ground_commands.Refused as e:
            self.reply(token, None, str(e))
            return
        if command["kind"] == "speed":
            self.speed = float(command["speed"])
        if command["kind"] in ("speed", "resume"):
            self._anchor = (time.monotonic(), self.m.now_s())
        self.reply(token, entry, None)
        if command["kind"] == "end":
            self._publish(force=True)
            raise ground_commands.Ended

    def _publish(self, force=False):
        """Hand the new rows, journal entries and state to the server."""
        m = self.m
        rows = m.telemetry(start_row=self._rows)
        self._rows += len(rows)
        events = [dict(e) for e in m.journal.events[self._events:]]
        self._events += len(events)
        now = time.monotonic()
        page = None
        self._stale = self._stale or bool(events)
        # A new status (the mission complete or aborted) goes with the page's state at once:
        # the page's ending, badge and banner read it.
        changed = m.status != getattr(self, "_page_status", None)
        if force or changed or (self._stale and now - self._page_at >= PAGE_EVERY_S) \
                or now - self._page_at > 2:
            page = self.page_state()
            self._page_at, self._stale, self._page_status = now, False, m.status
        self.publish({"rows": rows, "events": events, "session": self.session(), "page": page,
                      "final": self.done.is_set() or self.station.ended})

    def session(self) -> dict:
        """The live session's state: clock, speed, mode, status, what may be commanded."""
        m = self.m
        return {"t_s": m.now_s(), "mode": m.current_mode, "status": m.status,
                "speed": self.speed, "paused": self.station.paused,
                "ended": self.station.ended, "faults": len(m.cfg.faults),
                "plan": list(m.plan), "next_mode": m.next_mode,
                "in_flight": m.mode_in_flight is not None,
                "bright_gate": bool(m.cfg.star_tracker.bright_gate), "wall_s": self.wall_s(),
                "window": list(m.cfg.star_tracker.magnitude_window)}

    def page_state(self) -> dict:
        """The page's journal state (:func:`allsky.apps.replay.journal_data`) now."""
        m = self.m
        summary = m.summary()
        timeline = [dict(r) for r in summary["modes"]]
        if m.mode_in_flight is not None:
            timeline.append({"mode": m.current_mode, "start_s": float(m.mode_start_s),
                             "end_s": m.now_s(), "exit": ""})
        out = replay.journal_data(m.cfg, summary, timeline, m.now_s())
        out["window"] = list(m.cfg.star_tracker.magnitude_window)
        out["active_faults"] = [
            {"index": i, "text": f["text"]} for i, f in enumerate(out["faults"])
            if f["end_s"] is None]
        return out


class Server:
    """The session's web server: one page, one WebSocket, the token, the clients.

    Parameters
    ----------
    flight : Flight
        The mission flown.
    host, port : str, int
        Where to listen (port 0: any free port).
    page : callable
        ``page(ws_origin) -> str``: the page's HTML for the WebSocket's origin.
    hello : dict
        What every client gets first (the page's static data).
    allow_remote : bool
        The session is open beyond this machine (the page says so).
    """

    def __init__(self, flight, host, port, page, hello, allow_remote=False):
        self.flight = flight
        self.host, self.port = host, int(port)
        self.page = page
        self.hello = hello
        self.allow_remote = allow_remote
        #: the token that commands, and the one that watches only
        self.token = secrets.token_urlsafe(24)
        self.watch_token = secrets.token_urlsafe(24)
        self.loop = None
        self.clients = set()
        self.table = np.empty((0, len(replay.COLUMNS)))
        self.n_rows = 0
        self.journal = []
        self.page_state = None
        self.page_version = 0
        self.session = {}
        self.final = False
        self.written = None  #: what the session's end wrote (told to the clients)
        self.thread = threading.Thread(target=self._serve, name="allsky-server", daemon=True)
        self._ready = threading.Event()
        self._stop = None
        self._cache = {}
        self.error = None

    # -- lifecycle (main thread) ---------------------------------------------------
    def start(self) -> str:
        """Bind and serve in the server's thread; returns the session's URL."""
        self.thread.start()
        self._ready.wait()
        if self.error is not None:
            raise self.error
        return self.url()

    def url(self, watch=False) -> str:
        """The session's URL, with the token (``watch``: the one that watches only)."""
        host = f"[{self.host}]" if ":" in self.host else self.host
        return f"http://{host}:{self.port}/?token={self.watch_token if watch else self.token}"

    def stop(self, timeout=5.0):
        """Tell the clients the session ended, close them, stop serving.

        Waits at most ``timeout`` [s] for the shutdown, and as long again for
        the server's thread.
        """
        if self.loop is None or self._stop is None:
            return
        asyncio.run_coroutine_threadsafe(self._shutdown(), self.loop).result(timeout)
        self.thread.join(timeout)

    def _serve(self):
        with _LogLine(self._tokens()):
            self._serve_logged()

    def _serve_logged(self):
        try:
            from aiohttp import web
        except ImportError as e:  # pragma: no cover - a dependency of allsky
            self.error = ServeError(f"allsky serve needs aiohttp ({e}); pip install aiohttp")
            self._ready.set()
            return
        self.loop = asyncio.new_event_loop()
        asyncio.set_event_loop(self.loop)
        @web.middleware
        async def guard(request, handler):
            return await self._guard(request, handler)

        app = web.Application(middlewares=[guard], client_max_size=64 * 1024)
        app.router.add_get("/", self._get_page)
        app.router.add_get("/ws", self._get_ws)
        runner = web.AppRunner(app, access_log=None, handle_signals=False)
        self.loop.run_until_complete(runner.setup())
        try:
            sock = _listen(self.host, self.port)
        except OSError as e:
            self.error = ServeError(f"cannot listen on {self.host}:{self.port}: "
                                    f"{e.strerror or e}")
            self._ready.set()
            return
        self.port = sock.getsockname()[1]
        self.loop.run_until_complete(web.SockSite(runner, sock).start())
        self._stop = asyncio.Event()
        self._ready.set()
        self.loop.run_until_complete(self._stop.wait())
        self.loop.run_until_complete(runner.cleanup())
        self.loop.close()

    async def _shutdown(self):
        for c in list(self.clients):
            c.closed = True
            try:
                await self._flush(c)
                # The rest of the journal, whether or not it acknowledged the last update.
                await c.ws.send_str(json.dumps(self._update(c), allow_nan=False))
                await c.ws.send_str(json.dumps({"type": "ended", "written": self.written or [],
                                                "session": self.session}))
                await c.ws.close()
            except Exception:  # noqa: BLE001, S110 - a client gone already
                pass
        self._stop.set()

    # -- from the flight's thread -------------------------------------------------
    def publish(self, update):
        """The flight's update, handed over from its thread.

        ``update`` is a dict: ``rows`` (new telemetry rows), ``events`` (new
        journal entries), ``session``, ``page`` (page state or None), ``final``.
        """
        if self.loop is not None:
            self.loop.call_soon_threadsafe(self._take_update, update)

    def reply(self, token, entry, error):
        """A command's outcome, handed over from the flight's thread.

        ``token`` is ``(client, id)``, whoever sent the command and its id;
        ``entry`` the journal entry of a command taken, ``error`` the reason
        it was refused (None when taken).
        """
        if self.loop is not None:
            self.loop.call_soon_threadsafe(self._send_reply, token, entry, error)

    def _take_update(self, update):
        rows = update["rows"]
        if len(rows):
            if self.table.shape[0] < self.n_rows + len(rows):
                grown = np.empty((max(2 * self.table.shape[0], self.n_rows + len(rows), 4096),
                                  rows.shape[1]))
                grown[: self.n_rows] = self.table[: self.n_rows]
                self.table = grown
            self.table[self.n_rows: self.n_rows + len(rows)] = rows
            self.n_rows += len(rows)
        self.journal.extend(update["events"])
        self.session = update["session"]
        if update["page"] is not None:
            self.page_state = update["page"]
            self.page_version += 1
        self.final = self.final or update["final"]
        for c in self.clients:
            c.wake.set()

    def _send_reply(self, token, entry, error):
        client, ident = token
        if client in self.clients:
            msg = ({"type": "done", "id": ident, "entry": entry} if error is None
                   else {"type": "refused", "id": ident, "error": error})
            client.outbox.append(msg)
            client.wake.set()

    # -- HTTP ------------------------------------------------------------------------
    def _token_of(self, request):
        given = request.query.get("token", "")
        if hmac.compare_digest(given.encode(), self.token.encode()):
            return "command"
        if hmac.compare_digest(given.encode(), self.watch_token.encode()):
            return "watch"
        return None

    def _host_ok(self, request) -> bool:
        """The Host a browser asked for is this session's (loopback: no other name)."""
        host = clean_host(request.headers.get("Host"))
        if host is None:
            return False
        if self.allow_remote:
            return True
        name, _, port = host.rpartition(":")
        return port == str(self.port) and is_loopback(name)

    async def _guard(self, request, handler):
        """Every request: the token, and on loopback this machine's name; then safe headers."""
        from aiohttp import web

        if self._token_of(request) is None:
            return web.Response(status=403, text="403: forbidden: this allsky session needs "
                                "its token (the URL allsky serve printed)\n")
        if clean_host(request.headers.get("Host")) is None:
            return web.Response(status=400, text="400: bad request: a Host header "
                                "HOST[:PORT] is needed\n")
        if not self._host_ok(request):
            return web.Response(status=403, text="403: forbidden: not this session's host\n")
        response = await handler(request)
        response.headers["Referrer-Policy"] = "no-referrer"
        response.headers["X-Content-Type-Options"] = "nosniff"
        response.headers["Cache-Control"] = "no-store"
        return response

    async def _get_page(self, request):
        from aiohttp import web

        origin = f"ws://{clean_host(request.headers.get('Host'))}"  # checked by _guard
        return web.Response(text=self.page(origin), content_type="text/html", charset="utf-8",
                            headers={"X-Frame-Options": "DENY",
                                     "Content-Security-Policy": "frame-ancestors 'none'"})

    def _origin_ok(self, request) -> bool:
        """A browser's WebSocket comes from this session's page (no Origin: not a browser)."""
        origin = request.headers.get("Origin")
        host = clean_host(request.headers.get("Host"))
        return origin is None or origin.lower() == f"http://{host}"

    async def _get_ws(self, request):
        from aiohttp import WSMsgType, web

        if not self._origin_ok(request):
            return web.Response(status=403, text="403: forbidden: a page of another origin\n")
        # No per-message compression: on a loopback or a classroom LAN it costs CPU for nothing.
        ws = web.WebSocketResponse(heartbeat=20.0, max_msg_size=64 * 1024, compress=False)
        await ws.prepare(request)
        client = _Client(ws, self._token_of(request) == "command")
        try:
            since = float(request.query["since_s"]) if "since_s" in request.query else None
            client.since_s = since if since is not None and math.isfinite(since) else None
            client.journal_had = max(0, int(request.query.get("journal", "0")))
        except ValueError:
            client.since_s, client.journal_had = None, 0
        self.clients.add(client)
        self.flight.clients = len(self.clients)
        sender = asyncio.ensure_future(self._sender(client))
        try:
            async for msg in ws:
                if msg.type != WSMsgType.TEXT:
                    continue
                try:
                    self._received(client, msg.data)
                except Exception as e:  # noqa: BLE001 - one line, an answer; the session goes on
                    print(f"allsky: serve: a malformed message refused: "
                          f"{_one_line(f'{type(e).__name__}: {e}', self._tokens())}",
                          file=sys.stderr)
                    client.outbox.append({"type": "error", "error": "malformed message"})
                    client.wake.set()
        finally:
            self.clients.discard(client)
            self.flight.clients = len(self.clients)
            client.closed = True
            client.wake.set()
            await sender
        return ws

    def _tokens(self):
        return (self.token, self.watch_token)

    def _received(self, client, text):
        """One text message: an acknowledgement or a command; anything else is answered."""
        try:
            msg = json.loads(text)
        except (ValueError, RecursionError):
            msg = None
        kind = msg.get("type") if isinstance(msg, dict) else None
        if not isinstance(kind, str) or kind not in ("ack", "command"):
            print(f"allsky: serve: a message that is not the session's refused "
                  f"({len(text)} characters)", file=sys.stderr)
            client.outbox.append({"type": "error", "error": "not a message of this session: "
                                  'give {"type": "ack"} or {"type": "command", ...}'})
            client.wake.set()
            return
        if kind == "ack":
            client.acked = True
            client.wake.set()
        elif kind == "command":
            self._command(client, msg.get("id"), msg.get("command"))

    def _command(self, client, ident, command):
        from allsky.config import ConfigError

        def refuse(why):
            client.outbox.append({"type": "refused", "id": ident, "error": why})
            client.wake.set()

        if not client.can_command:
            return refuse("this link watches the session; commands need the commanding link")
        if self.final:
            return refuse("the session has ended")
        if ident is not None and (isinstance(ident, bool) or not isinstance(ident, (int, str))):
            ident = None
        try:
            checked = ground_commands.validate(command, self.flight.m.cfg)
        except ConfigError as e:
            return refuse(str(e))
        except (TypeError, ValueError, RecursionError) as e:  # a shape no rule foresaw
            print(f"allsky: serve: a malformed command refused ({type(e).__name__})",
                  file=sys.stderr)
            return refuse(f"malformed command: {type(e).__name__}")
        self.flight.commands.put((checked, (client, ident)))

    # -- updates -----------------------------------------------------------------------
    def _encode(self, start, stop, budget):
        key = (start, stop, budget)
        if key not in self._cache:
            if len(self._cache) > 64:
                self._cache.clear()
            rows = _rows(self.table, start, stop, budget)
            self._cache[key] = replay.encode_rows(rows) if len(rows) else None
        return self._cache[key]

    def _hello(self, client) -> dict:
        """The first message: the page's data, and the session so far (or what was missed)."""
        stop, start, have = self.n_rows, 0, 0
        if client.since_s is not None:  # a page that reconnects: rows after its last one
            times = self.table[:stop, replay.INDEX["time"]]
            start = int(np.searchsorted(times, client.since_s, side="right"))
            have = min(client.journal_had, len(self.journal))
        client.rows_sent = stop
        client.journal_sent = len(self.journal)
        client.page_sent = self.page_version
        return {"type": "hello", "data": self.hello,
                "columns": self._encode(start, stop, CATCH_UP_ROWS) if stop > start else None,
                "journal": self.journal[have:], "page": self.page_state,
                "session": self.session,
                "can_command": client.can_command, "clients": len(self.clients),
                "watch_url": self.url(watch=True) if client.can_command else None,
                "remote": self.allow_remote}

    def _update(self, client):
        stop = self.n_rows
        msg = {"type": "update", "session": self.session, "clients": len(self.clients)}
        if stop > client.rows_sent:
            msg["columns"] = self._encode(client.rows_sent, stop, ROWS_PER_UPDATE)
            client.rows_sent = stop
        if len(self.journal) > client.journal_sent:
            msg["journal"] = self.journal[client.journal_sent:]
            client.journal_sent = len(self.journal)
        if self.page_version != client.page_sent:
            msg["page"] = self.page_state
            client.page_sent = self.page_version
        return msg

    async def _flush(self, client):
        """Send a client the replies to its commands, in order."""
        while client.outbox:
            await client.ws.send_str(json.dumps(client.outbox.pop(0), allow_nan=False))

    async def _sender(self, client):
        """Send a client its updates: one at a time, each after the last was acknowledged."""
        ws = client.ws
        try:
            while self.page_state is None and not client.closed:  # the flight's first state
                client.wake.clear()
                await client.wake.wait()
            if client.closed:
                return
            await ws.send_str(json.dumps(self._hello(client), allow_nan=False))
            client.acked = False
            last = time.monotonic()
            while not client.closed:
                await client.wake.wait()
                client.wake.clear()
                await self._flush(client)
                if not client.acked or client.closed:
                    continue
                wait = UPDATE_EVERY_S - (time.monotonic() - last)
                if wait > 0:  # not yet: woken again then (or by a reply before)
                    self.loop.call_later(wait, client.wake.set)
                    continue
                msg = self._update(client)
                last = time.monotonic()
                client.acked = False
                await ws.send_str(json.dumps(msg, allow_nan=False))
        except (ConnectionError, RuntimeError):
            return
        except Exception as e:  # noqa: BLE001 - one line on stderr; the session goes on
            print(f"allsky: serve: a client's updates stopped: {type(e).__name__}: {e}",
                  file=sys.stderr)
            await ws.close()


def _listen(host, port):
    """A listening TCP socket on ``host``:``port`` (0: a free port)."""
    import socket

    info = socket.getaddrinfo(host, port, type=socket.SOCK_STREAM)[0]
    sock = socket.socket(info[0], socket.SOCK_STREAM)
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
    try:
        sock.bind(info[4])
        sock.listen(128)
    except OSError:
        sock.close()
        raise
    sock.setblocking(False)
    return sock


class _Client:
    """One WebSocket client of the session."""

    def __init__(self, ws, can_command):
        self.ws = ws
        self.can_command = can_command
        self.wake = asyncio.Event()
        self.wake.set()
        self.acked = True
        self.outbox = []
        self.closed = False
        self.rows_sent = 0
        self.journal_sent = 0
        self.page_sent = 0
        self.since_s = None  #: [s] a reconnecting page's last row
        self.journal_had = 0  #: the journal entries it has


def static_data(cfg, scenario) -> dict:
    """What every client gets first: the page's data that the flight does not change.

    ``cfg`` is the scenario flown; ``scenario`` is who flew what
    (:func:`allsky.apps.replay.describe_scenario`).
    """
    from allsky.config.faults import REGISTER_BITS_KEY
    from allsky.vehicle import sky
    from allsky.vocabulary import AXES, FAULT_KINDS, GROUND_COMMANDS

    interval = float(cfg.mission.frame_s) * int(cfg.mission.telemetry_every_frames)
    config = replay.config_data(cfg, interval)
    sky_base = replay.sky_data(cfg, None, [])
    del sky_base["targets"]
    return {"live": True, "format": replay.DATA_FORMAT, "diagram": replay.diagram(),
            "sky": sky_base, "config": config, "vehicle": replay.vehicle_data(cfg),
            "mission": replay.mission_data(cfg, None, scenario),
            "notes": [*replay.notes(config), LIVE_NOTE],
            "ground": {"commands": [c._asdict() for c in GROUND_COMMANDS],
                       "fault_kinds": [k._asdict() for k in FAULT_KINDS],
                       "axes": list(AXES), "registers": list(REGISTER_BITS_KEY),
                       "stars": list(sky.star_names()), "speeds": list(SPEEDS)}}


def open_browser(url):
    """Open the browser on ``url`` without putting its token on a command line.

    The browser's command line is readable by every local user (``ps``); it
    gets a local file, readable by this user only, that sends it on to the
    URL. Returns the file's directory (removed at the session's end), or None
    when no browser could be started (the printed line says where to go).
    """
    import html
    import tempfile
    import webbrowser

    folder = tempfile.mkdtemp(prefix="allsky-open-")  # mode 0700
    path = os.path.join(folder, "open.html")
    target = html.escape(url, quote=True)
    fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
    with os.fdopen(fd, "w", encoding="utf-8") as f:
        f.write(f'<!doctype html><meta charset="utf-8"><meta name="referrer" '
                f'content="no-referrer"><meta http-equiv="refresh" content="0;url={target}">'
                f'<title>allsky</title><a href="{target}">allsky live</a>\n')
    try:
        webbrowser.open("file://" + path)
    except Exception:  # noqa: BLE001 - no browser: the line printed says where
        shutil.rmtree(folder, ignore_errors=True)
        return None
    return folder


def check_host(host, allow_remote) -> None:
    """Refuse a host beyond this machine unless ``allow_remote`` (ServeError, exit 2).

    ``host`` is the name or address ``--host`` asked to serve on.
    """
    if not is_loopback(host) and not allow_remote:
        raise ServeError(f"--host {host} would open the session beyond this machine: anyone "
                         "who can reach it with the link could command the mission; add "
                         "--allow-remote to mean it")


def run_from_cli(cfg, args) -> int:
    """``allsky serve``: serve the live session until the page or a signal ends it.

    Prints one line on stdout, ``allsky: serving http://HOST:PORT/?token=TOKEN``,
    while the session lasts; at its end the report (as ``allsky run``) and
    what was written. The page's end button ends it with the mission's exit
    code (0, or 1 if it ended aborted); Ctrl-C, SIGTERM or SIGHUP with 130.

    ``cfg`` is the scenario the command line loaded and ``args`` the parsed
    command line (:mod:`allsky.apps.cli`); returns the exit status.
    """
    from allsky.apps.output import (
        TELEMETRY_SUFFIXES,
        Interrupted,
        OutputError,
        check_output,
        write_atomic,
    )
    from allsky.apps.report import format_report, tracker_star, where_stopped, write_outputs
    from allsky.apps.summaries import summary_text
    from allsky.apps.telemetry_files import file_format
    from allsky.apps.telemetry_files import write as write_telemetry
    from allsky.config import ConfigError
    from allsky.config.dispersions import disperse, format_drawn

    if args.json == "-":
        raise OutputError("--json", "-", "stdout carries the serving line: give a file")
    check_output("--json", args.json)
    check_output("--telemetry", args.telemetry, suffixes=TELEMETRY_SUFFIXES)
    if args.telemetry:
        file_format(args.telemetry)
    check_output("--html", args.html, suffixes=(".html", ".htm"))
    check_output("--save-commands", args.save_commands, suffixes=(".toml",))
    try:
        check_host(args.host, args.allow_remote)
    except ServeError as e:
        raise ConfigError(None, rule=str(e)) from None
    if not 0 <= args.port <= 65535:
        raise ConfigError(None, rule=f"--port {args.port}: must be 0 (any free port) to 65535")
    scenario_dict = cfg.as_dict()  # before the dispersions are drawn: the log draws them again
    cfg, drawn = disperse(cfg)
    if drawn:
        print(format_drawn(cfg.mission.seed, drawn), file=sys.stderr)
    about = replay.describe_scenario(getattr(args, "scenario", None),
                                     getattr(args, "overrides", ()))
    hello = static_data(cfg, about)
    holder = {}

    def page(origin):
        return replay.render_html({"live": True, "mission": hello["mission"]}, connect=origin)

    flight = Flight(cfg, args.speed, lambda u: holder["server"].publish(u),
                    lambda *a: holder["server"].reply(*a), args.pause_when_alone)
    server = Server(flight, args.host, args.port, page, hello, args.allow_remote)
    holder["server"] = server
    try:
        url = server.start()
    except ServeError as e:
        raise ConfigError(None, rule=str(e)) from None
    flight.start()
    print(f"allsky: serving {url}", flush=True)
    opener = None
    if not args.no_browser:
        opener = open_browser(url)

    signalled = []

    def end_by_signal(signum, frame):
        if signalled:  # a second one: stop now
            raise KeyboardInterrupt
        signalled.append(signum)
        flight.commands.put(({"kind": "end"}, (None, None)))

    from allsky.apps.output import ENDING_SIGNALS

    # A hang-up (the terminal closed, ssh dropped) ends the session as Ctrl-C does: the
    # summary, telemetry and command log are written.
    before = {sig: signal.signal(sig, end_by_signal) for sig in ENDING_SIGNALS}
    try:
        while not flight.done.wait(0.2):
            pass
    finally:
        for sig, handler in before.items():
            signal.signal(sig, handler)
    if flight.error is not None and not isinstance(flight.error, ground_commands.Ended):
        server.stop()
        raise flight.error
    m = flight.m
    summary = m.summary()
    if drawn:
        summary["dispersions"] = drawn
    from allsky.apps.report import report_width

    print(format_report(summary, tracker_star(cfg), scenario=about, width=report_width()))
    outputs = []
    if args.json:
        outputs.append((f"JSON summary {args.json}", lambda: write_atomic(
            args.json, summary_text(summary), option="--json")))
    if args.telemetry:
        outputs.append((f"telemetry {args.telemetry}", lambda: write_telemetry(
            args.telemetry, m.telemetry(), option="--telemetry")))
    if args.html and len(m.telemetry()):
        outputs.append((f"replay {args.html}", lambda: replay.write_replay(
            args.html, m.telemetry(), summary, cfg, option="--html", scenario=about)))
    if args.save_commands:
        note = f"scenario {about['name']}" + (f", --set {' '.join(about['overrides'])}"
                                              if about["overrides"] else "")
        outputs.append((f"command log {args.save_commands}", lambda: write_atomic(
            args.save_commands, ground_commands.log_text(flight.station.log, scenario_dict,
                                                          note), option="--save-commands")))
    written, failed = write_outputs(outputs)
    server.written = written
    server.stop()
    if opener is not None:
        shutil.rmtree(opener, ignore_errors=True)
    for what in written:
        print(f"wrote {what}")
    if signalled:
        saved = ", ".join(["the report"] + written)
        failures = "".join(f"; {e}" for e in failed)
        raise Interrupted(f"session ended at {where_stopped(m)}; written: {saved}{failures}")
    for e in failed:
        print(f"allsky: error: {e}", file=sys.stderr)
    if failed:
        return 2
    return 1 if m.status == "aborted" else 0
