"""``allsky serve`` on loopback, through its HTTP and WebSocket protocol (no browser).

Each test starts the command as a user does (``allsky serve --no-browser``),
reads the one line it prints, and talks to it with aiohttp's client: the
token and Origin rules, a watch-only link, a client that reconnects, the
end by command and by Ctrl-C, and the saved session flown again by ``allsky
run --commands`` to the same summary and telemetry, bit for bit.
"""

import asyncio
import contextlib
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path
from urllib.parse import urlsplit

import numpy as np
import pytest

aiohttp = pytest.importorskip("aiohttp")

ALLSKY = [sys.executable, "-m", "allsky"]
#: [s] the longest any step of these tests waits (a bound, never a verdict).
TIMEOUT_S = 120.0


class Session:
    """A running ``allsky serve`` and its URL."""

    def __init__(self, *args, env=None, browser=False):
        self.proc = subprocess.Popen([*ALLSKY, "serve", *([] if browser else ["--no-browser"]),
                                      *args],
                                     stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                                     env={**os.environ, **(env or {})})
        line = self.proc.stdout.readline()
        assert line.startswith("allsky: serving http://"), (line, self.proc.stderr.read())
        self.line = line
        self.url = line.split()[-1]
        parts = urlsplit(self.url)
        self.origin = f"{parts.scheme}://{parts.netloc}"
        self.token = parts.query.split("=", 1)[1]
        self.ws_url = f"ws://{parts.netloc}/ws?token={self.token}"

    def finish(self, timeout=TIMEOUT_S):
        out, err = self.proc.communicate(timeout=timeout)
        return self.proc.returncode, self.line + out, err

    def kill(self):
        if self.proc.poll() is None:
            self.proc.kill()
            self.proc.communicate()


@contextlib.contextmanager
def serving(*args, **kwargs):
    s = Session(*args, **kwargs)
    try:
        yield s
    finally:
        s.kill()


class Client:
    """A WebSocket client of a session: acknowledges every update, keeps what came."""

    def __init__(self, http, ws):
        self.http, self.ws = http, ws
        self.journal, self.session, self.hello = [], {}, None
        self.rows, self.answers, self.next_id = 0, {}, 1

    @classmethod
    async def connect(cls, url, origin=None, query=""):
        http = aiohttp.ClientSession()
        headers = {"Origin": origin} if origin else {}
        ws = await http.ws_connect(url + query, headers=headers, max_msg_size=0)
        return cls(http, ws)

    async def receive(self):
        """One message, taken in (an update acknowledged); None once closed."""
        msg = await asyncio.wait_for(self.ws.receive(), TIMEOUT_S)
        if msg.type != aiohttp.WSMsgType.TEXT:
            return None
        data = json.loads(msg.data)
        kind = data["type"]
        if kind == "hello":
            self.hello = data
        if kind in ("hello", "update"):
            self.journal += data.get("journal") or []
            self.rows += (data.get("columns") or {}).get("n", 0)
            with contextlib.suppress(ConnectionError):  # the session closing meanwhile
                await self.ws.send_str(json.dumps({"type": "ack"}))
        if kind in ("done", "refused"):
            self.answers[data["id"]] = data
        if "session" in data:
            self.session = data["session"]
        return data

    async def until(self, test):
        """Receive until ``test(self)``; returns False if the session closed first."""
        while not test(self):
            if await self.receive() is None:
                return False
        return True

    async def command(self, command):
        """Send a command; returns the answer (``done`` with the entry, or ``refused``)."""
        ident = self.next_id
        self.next_id += 1
        await self.ws.send_str(json.dumps({"type": "command", "id": ident, "command": command}))
        await self.until(lambda c: ident in c.answers)
        return self.answers[ident]

    async def close(self):
        await self.ws.close()
        await self.http.close()


async def http_get(url, headers=None):
    async with aiohttp.ClientSession() as http, http.get(url, headers=headers or {}) as r:
        return r.status, await r.text(), dict(r.headers)


def test_every_request_needs_the_session_s_token():
    with serving() as s:
        base = s.origin
        assert asyncio.run(http_get(f"{base}/"))[0] == 403
        assert asyncio.run(http_get(f"{base}/?token=wrong"))[0] == 403
        assert asyncio.run(http_get(f"{base}/ws"))[0] == 403
        assert asyncio.run(http_get(f"{base}/etc/passwd"))[0] == 403
        assert asyncio.run(http_get(f"{base}/etc/passwd?token={s.token}"))[0] == 404
        status, page, headers = asyncio.run(http_get(s.url))
        assert status == 200 and "allsky live" in page
        host = urlsplit(s.url).netloc
        assert f"connect-src ws://{host};" in page  # the page reaches its session only
        assert headers["Referrer-Policy"] == "no-referrer"
        # A name that is not this machine's (DNS rebinding) is refused, token or not.
        port = urlsplit(s.url).port
        assert asyncio.run(http_get(s.url, {"Host": f"attacker.example:{port}"}))[0] == 403


def test_the_websocket_refuses_a_page_of_another_origin():
    async def check(s):
        with pytest.raises(aiohttp.WSServerHandshakeError) as e:
            await Client.connect(s.ws_url, origin="http://attacker.example")
        assert e.value.status == 403
        c = await Client.connect(s.ws_url, origin=s.origin)
        await c.until(lambda c: c.hello is not None)
        assert c.hello["can_command"] and c.hello["data"]["live"]
        await c.close()

    with serving() as s:
        asyncio.run(check(s))


def test_a_host_beyond_this_machine_needs_allow_remote():
    r = subprocess.run([*ALLSKY, "serve", "--no-browser", "--host", "192.0.2.7"],
                       capture_output=True, text=True, timeout=TIMEOUT_S, check=False)
    assert r.returncode == 2 and r.stdout == ""
    assert r.stderr.startswith("allsky: error: --host 192.0.2.7 would open the session")
    assert "--allow-remote" in r.stderr and len(r.stderr.splitlines()) == 1


def test_a_watch_link_watches_and_cannot_command():
    async def check(s):
        c = await Client.connect(s.ws_url)
        await c.until(lambda c: c.hello is not None)
        watch = urlsplit(c.hello["watch_url"]).query.split("=", 1)[1]
        w = await Client.connect(s.ws_url.replace(s.token, watch))
        await w.until(lambda w: w.hello is not None)
        assert not w.hello["can_command"] and w.hello["watch_url"] is None
        answer = await w.command({"kind": "pause"})
        assert answer["type"] == "refused" and "watches" in answer["error"]
        answer = await c.command({"kind": "warp"})
        assert answer["type"] == "refused" and answer["error"].startswith("command.kind")
        await w.close()
        await c.close()

    with serving() as s:
        asyncio.run(check(s))


def test_a_client_that_reconnects_catches_up_from_the_journal(tmp_path):
    """Away for a while, back with its last time and journal count: nothing is missing."""
    summary = tmp_path / "s.json"

    async def check(s):
        a = await Client.connect(s.ws_url)
        await a.until(lambda c: c.session.get("t_s", 0) > 200.0)
        seen, last = len(a.journal), a.session["t_s"]
        await a.close()
        late = await Client.connect(s.ws_url)  # a client that comes late: the session so far
        await late.until(lambda c: c.hello is not None)
        await asyncio.sleep(1.0)  # the mission flies on meanwhile
        b = await Client.connect(s.ws_url, query=f"&since_s={last}&journal={seen}")
        await b.until(lambda c: c.hello is not None)
        assert b.hello["columns"]["n"] > 0  # the rows flown while it was away
        assert len(b.hello["journal"]) > 0  # and the journal's entries
        await b.until(lambda c: c.session.get("t_s", 0) > last + 300.0)
        answer = await b.command({"kind": "end"})
        assert answer["type"] == "done"
        await b.until(lambda c: False)  # to the session's end
        await late.until(lambda c: False)
        for c in (b, late):
            await c.close()
        return a.journal + b.journal, late.journal

    with serving("--speed", "200", "--json", str(summary)) as s:
        journal, late = asyncio.run(check(s))
        code, _, err = s.finish()
    assert code == 0, err
    events = json.loads(summary.read_text())["events"]
    assert late == events
    assert journal == events


def test_a_session_ended_from_the_page_is_flown_again_exactly(tmp_path):
    """Commands over the WebSocket, the end button's command; the log gives the same flight."""
    out = {k: tmp_path / f"live.{k}" for k in ("json", "parquet", "toml")}

    async def fly(s):
        c = await Client.connect(s.ws_url)
        await c.until(lambda c: c.session.get("t_s", 0) > 300.0)
        fault = await c.command({"kind": "fault", "fault_kind": "tracker_dropout",
                                 "duration_s": 3.0})
        assert fault["type"] == "done" and fault["entry"]["fault"] == 0
        await c.until(lambda c: c.session.get("t_s", 0) > 700.0)
        target = await c.command({"kind": "target", "star": "Vega"})
        assert target["entry"]["text"] == "new target Vega"
        await c.until(lambda c: c.session.get("t_s", 0) > 900.0)
        end = await c.command({"kind": "end"})
        await c.until(lambda c: False)
        await c.close()
        return fault["entry"], target["entry"], end["entry"], c.journal

    with serving("--speed", "400", "--json", str(out["json"]), "--telemetry",
                 str(out["parquet"]), "--save-commands", str(out["toml"])) as s:
        fault, target, end, journal = asyncio.run(fly(s))
        code, stdout, err = s.finish()
    assert code == 0, err
    assert "wrote command log" in stdout and stdout.splitlines()[0] == s.line.strip()
    live = json.loads(out["json"].read_text())
    assert [e for e in live["events"] if e["kind"] == "ground_command"] == [fault, target, end]
    assert journal == live["events"]
    again = {k: tmp_path / f"again.{k}" for k in ("json", "parquet")}
    r = subprocess.run([*ALLSKY, "run", "--commands", str(out["toml"]), "--json",
                        str(again["json"]), "--telemetry", str(again["parquet"]), "--quiet"],
                       capture_output=True, text=True, timeout=TIMEOUT_S, check=False)
    assert r.returncode == 0, r.stderr
    assert json.loads(again["json"].read_text()) == live
    from allsky.apps.telemetry_files import read

    a, b = read(out["parquet"])[0], read(again["parquet"])[0]
    assert a.shape == b.shape and np.array_equal(a.view(np.uint64), b.view(np.uint64))


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGHUP])
def test_ctrl_c_ends_the_session_writing_what_run_writes(tmp_path, sig):
    """Ctrl-C, and a hang-up (the terminal closed): summary, telemetry and command log."""
    log = tmp_path / "s.toml"
    with serving("--speed", "50", "--save-commands", str(log), "--json",
                 str(tmp_path / "s.json"), "--telemetry", str(tmp_path / "t.csv")) as s:
        time.sleep(2.0)
        s.proc.send_signal(sig)
        code, _, err = s.finish()
    assert code == 130, err
    assert err.splitlines()[-1].startswith("allsky: interrupted; session ended at t = ")
    assert "written: the report, JSON summary" in err and "command log" in err
    assert "telemetry" in err and (tmp_path / "t.csv").stat().st_size > 0
    assert json.loads((tmp_path / "s.json").read_text())["status"]
    assert not [p for p in tmp_path.iterdir() if ".tmp" in p.name]
    text = log.read_text()
    assert text.rstrip().endswith('kind = "end"') and "[scenario.mission]" in text


def test_pause_when_alone_waits_for_a_client():
    """Flown while someone watches, held while no one does.

    The first client may connect before the flight starts (the server loads
    or compiles its loops first, longer on a loaded machine), so the test
    watches it fly, leaves, and comes back 1.5 s later: at x50 the flight
    would have flown 75 s alone; held, it has flown at most what it flew
    before the server saw the client go (a slice, 2.5 s at x50, and the
    server's reaction).
    """
    async def check(s):
        a = await Client.connect(s.ws_url)
        await a.until(lambda c: c.session.get("t_s", 0) > 10.0)
        await a.close()
        left = a.session["t_s"]
        await asyncio.sleep(1.5)
        b = await Client.connect(s.ws_url)
        await b.until(lambda c: c.hello is not None)
        back = b.hello["session"]["t_s"]
        await b.until(lambda c: c.session.get("t_s", 0) > back + 20.0)
        await b.command({"kind": "end"})
        await b.until(lambda c: False)
        await b.close()
        return left, back

    with serving("--pause-when-alone", "--speed", "50") as s:
        left, back = asyncio.run(check(s))
        code, _, err = s.finish()
    assert code == 0, err
    assert back - left < 20.0, (left, back)  # 1.5 s alone at x50 would have flown 75 s


@pytest.mark.parametrize("args, words", [
    (("--json", "-"), "--json"),
    (("--save-commands", "log.txt"), "--save-commands"),
    (("--port", "70000"), "--port 70000"),
])
def test_bad_options_exit_2_with_one_line(args, words, tmp_path):
    r = subprocess.run([*ALLSKY, "serve", "--no-browser", *args], capture_output=True,
                       text=True, timeout=TIMEOUT_S, cwd=tmp_path, check=False)
    assert r.returncode == 2 and r.stdout == ""
    assert r.stderr.startswith("allsky: error:") and words in r.stderr
    assert len(r.stderr.splitlines()) == 1


def test_run_commands_refuses_a_bad_log(tmp_path):
    log = tmp_path / "bad.toml"
    log.write_text('format = 1\n[[commands]]\nt_s = 3.0\nkind = "hold"\n')
    r = subprocess.run([*ALLSKY, "run", "--commands", str(log), "--quiet"],
                       capture_output=True, text=True, timeout=TIMEOUT_S, check=False)
    assert r.returncode == 2
    assert r.stderr.startswith("allsky: error: commands[0] = 'hold': a hold lasts until")


# -- the server's edges: malformed requests and messages, the Host, the token ------------------

def _raw(s, data: bytes) -> bytes:
    import socket

    parts = urlsplit(s.url)
    with socket.create_connection((parts.hostname, parts.port), timeout=TIMEOUT_S) as sock:
        sock.sendall(data)
        return sock.recv(4096)


def _malformed_requests(token: bytes, port: int) -> dict:
    get = b"GET /?token=" + token
    host = b"Host: 127.0.0.1:%d\r\n" % port
    return {
        "no Host": get + b" HTTP/1.1\r\n\r\n",
        "overlong line": get + b"&x=" + b"a" * 20000 + b" HTTP/1.1\r\n" + host + b"\r\n",
        "overlong header": get + b" HTTP/1.1\r\n" + host + b"X: " + b"a" * 20000 + b"\r\n\r\n",
        "2000 headers": get + b" HTTP/1.1\r\n" + host
        + b"".join(b"X%d: a\r\n" % i for i in range(2000)) + b"\r\n",
        "CL+TE": b"POST /?token=" + token + b" HTTP/1.1\r\n" + host
        + b"Content-Length: 4\r\nTransfer-Encoding: chunked\r\n\r\n0\r\n\r\n",
        "bytes": b"\x00\x01\xff\r\n\r\n",
        "Host with markup": get + b' HTTP/1.1\r\nHost: a"><script>x</script>\r\n\r\n',
    }


def test_malformed_http_is_answered_400_in_one_line_without_token_or_traceback():
    with serving("--speed", "1") as s:
        port = urlsplit(s.url).port
        for name, data in _malformed_requests(s.token.encode(), port).items():
            answer = _raw(s, data)
            assert answer.startswith(b"HTTP/1.") and b" 400 " in answer[:20], (name, answer)
        assert asyncio.run(http_get(s.url))[0] == 200  # the server is up
        s.proc.send_signal(signal.SIGINT)
        code, _, err = s.finish()
    assert code == 130
    assert "Traceback" not in err and s.token not in err, err
    assert all(line.startswith("allsky: ") for line in err.splitlines()), err


def test_host_is_compared_case_insensitively_and_escaped_under_allow_remote():
    with serving("--allow-remote", "--speed", "1") as s:
        port = urlsplit(s.url).port
        assert asyncio.run(http_get(s.url, {"Host": f"LOCALHOST:{port}"}))[0] == 200
        answer = _raw(s, b"GET /?token=" + s.token.encode()
                      + b' HTTP/1.1\r\nHost: x"><b>y</b>:1\r\n\r\n')
        assert b" 400 " in answer[:20] and b"<b>" not in answer, answer
        status, page, _ = asyncio.run(http_get(s.url, {"Host": f"Example.ORG:{port}"}))
        assert status == 200 and f"ws://example.org:{port}" in page


def test_malformed_websocket_messages_are_answered_and_the_journal_kept():
    async def check(s):
        c = await Client.connect(s.ws_url)
        await c.until(lambda c: c.hello is not None)
        bad = [{"type": "command", "id": 1, "command": {"kind": [1]}},
               {"type": "command", "id": 2, "command": {"kind": {"a": 1}}},
               {"type": "command", "id": 3, "command": [1, 2]}]
        for msg in bad:
            await c.ws.send_str(json.dumps(msg))
        for text in ["[" * 30000 + "]" * 30000, "[1]", "5", '{"type": ["x"]}', "{", "\x00"]:
            await c.ws.send_str(text)
        await c.until(lambda c: {1, 2, 3} <= set(c.answers))
        assert all(c.answers[i]["type"] == "refused" for i in (1, 2, 3))
        c.next_id = 10
        answer = await c.command({"kind": "speed", "speed": 50})
        assert answer["type"] == "done", answer
        await c.close()

    with serving("--speed", "1") as s:
        asyncio.run(check(s))
        s.proc.send_signal(signal.SIGINT)
        code, _, err = s.finish()
    assert code == 130 and "Traceback" not in err, err
    assert all(line.startswith("allsky: ") for line in err.splitlines()), err


def test_the_browser_gets_no_token_on_its_command_line(tmp_path):
    """The browser's argv is anyone's to read (ps): it names a private file that redirects."""
    seen = tmp_path / "argv.txt"
    browser = tmp_path / "browser.sh"
    browser.write_text(f'#!/bin/sh\nprintf "%s\\n" "$@" > {seen}\ncat "${{1#file://}}" >> '
                       f"{seen}.page\n")
    browser.chmod(0o755)
    with serving("--speed", "1", env={"BROWSER": f"{browser} %s"}, browser=True) as s:
        argv_text = None
        deadline = time.monotonic() + TIMEOUT_S
        while time.monotonic() < deadline and not (seen.exists()
                                                    and Path(f"{seen}.page").exists()):
            time.sleep(0.1)
        argv_text = seen.read_text()
        page = Path(f"{seen}.page").read_text()
        opened = Path(argv_text.strip()[len("file://"):])
        assert opened.stat().st_mode & 0o777 == 0o600  # this user's only
        s.proc.send_signal(signal.SIGINT)
        assert s.finish()[0] == 130
    assert s.token not in argv_text and argv_text.startswith("file://"), argv_text
    assert "http-equiv=\"refresh\"" in page and s.token in page
    assert not opened.exists()  # removed at the session's end


def _attacks(rng, token: bytes, port: int, n: int):
    """``n`` malformed HTTP requests and WebSocket messages, drawn from ``rng``."""
    import random as _random

    assert isinstance(rng, _random.Random)
    host = b"Host: 127.0.0.1:%d\r\n" % port
    get = b"GET /?token=" + token
    http, ws = [], []
    for k in range(n):
        kind = rng.randrange(8)
        if kind == 0:
            http.append(get + b"&x=" + b"a" * rng.randint(8200, 30000) + b" HTTP/1.1\r\n" + host
                        + b"\r\n")
        elif kind == 1:
            http.append(get + b" HTTP/1.1\r\n" + host + b"".join(
                b"X%d: %s\r\n" % (i, b"v" * rng.randint(1, 50)) for i in
                range(rng.randint(120, 3000))) + b"\r\n")
        elif kind == 2:
            http.append(get + b" HTTP/1.1\r\n" + rng.choice([b"", b"Host: \r\n",
                                                             b'Host: a"b\r\n', b"Host: x y\r\n",
                                                             b"Host: <i>\r\n"]) + b"\r\n")
        elif kind == 3:
            http.append(bytes(rng.randrange(256) for _ in range(rng.randint(1, 400)))
                        + b"\r\n\r\n")
        elif kind == 4:
            http.append(b"POST /?token=" + token + b" HTTP/1.1\r\n" + host
                        + b"Content-Length: 5\r\nTransfer-Encoding: chunked\r\n\r\n0\r\n\r\n")
        else:
            depth = rng.choice([1, 50, 3000, 30000])
            junk = [None, 1, "x", [1], {"a": 1}, [[]], True, 1e308]
            ws.append(rng.choice([
                "[" * depth + "]" * depth,
                json.dumps({"type": "command", "id": k, "command": {"kind": rng.choice(junk)}}),
                json.dumps({"type": rng.choice(junk), "id": k}),
                json.dumps({"type": "command", "id": rng.choice(junk),
                            "command": rng.choice(junk)}),
                json.dumps({"type": "command", "id": k, "command": {
                    "kind": "fault", "fault_kind": rng.choice(junk), "axis": rng.choice(junk)}}),
                "".join(chr(rng.randrange(1, 0x3000)) for _ in range(rng.randint(1, 200))),
            ]))
    return http, ws


def _attack_campaign(n, seed):
    import random as _random

    rng = _random.Random(seed)

    async def talk(s, ws_messages):
        c = await Client.connect(s.ws_url)
        await c.until(lambda c: c.hello is not None)
        for text in ws_messages:
            await c.ws.send_str(text)
        c.next_id = 10**6
        answer = await c.command({"kind": "speed", "speed": 50})
        assert answer["type"] == "done", answer
        await c.close()
        return answer

    with serving("--speed", "1") as s:
        port = urlsplit(s.url).port
        http, ws = _attacks(rng, s.token.encode(), port, n)
        for data in http:
            answer = _raw(s, data)
            assert answer.startswith(b"HTTP/1.") and answer[9:10] == b"4", (data[:80], answer)
        asyncio.run(talk(s, ws))
        assert asyncio.run(http_get(s.url))[0] == 200  # up
        s.proc.send_signal(signal.SIGINT)
        code, _, err = s.finish()
    assert code == 130 and "Traceback" not in err and s.token not in err, err
    assert all(line.startswith("allsky: ") for line in err.splitlines()), err
    return len(http), len(ws)


def test_a_short_attack_campaign_leaves_the_server_up():
    assert sum(_attack_campaign(24, "allsky serve attacks")) == 24


@pytest.mark.slow
def test_the_long_attack_campaign():
    """200 malformed HTTP requests and WebSocket messages (counts in docs/validation.md)."""
    n_http, n_ws = _attack_campaign(200, "allsky serve long attacks")
    print(f"\nserve attacks: {n_http} HTTP, {n_ws} WebSocket")
