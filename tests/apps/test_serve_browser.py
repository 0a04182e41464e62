"""The live page of ``allsky serve`` in a real headless browser (Debian's chromium).

A user's session: the page opened from the printed URL, a tracker dropout
injected and a new target uploaded with the page's own controls, the page
reloaded (a client that comes back catches up from the journal), the
session ended with the end button; then the saved command log flown again
by ``allsky run --commands`` gives the same summary and telemetry, bit for
bit. The token and the Origin rules are checked from the browser: no page
without the token, no WebSocket from a page of another origin, and the live
page itself can reach nothing but its session (its Content-Security-Policy).
"""

import json
import subprocess
import time

import numpy as np
import pytest

from tests.apps.test_replay_browser import new_driver
from tests.apps.test_serve import ALLSKY, TIMEOUT_S, Session

#: [s] polling step while the browser works (a bound is TIMEOUT_S; no verdict is timed).
STEP_S = 0.1
#: The live page has booted and can command.
READY = ("return !!(window.allsky && window.allsky.ready "
         "&& typeof window.allsky.command === 'function')")


def wait_for(driver, script, timeout=TIMEOUT_S):
    """Poll ``script`` (JavaScript returning a value) in the page until it is truthy."""
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        value = driver.execute_script(script)
        if value:
            return value
        time.sleep(STEP_S)
    raise AssertionError(f"not within {timeout} s: {script}")


@pytest.fixture(scope="module")
def driver():
    d = new_driver()
    try:
        yield d
    finally:
        d.quit()


@pytest.fixture(scope="module")
def live(tmp_path_factory):
    out = tmp_path_factory.mktemp("live")
    paths = {k: out / f"live.{k}" for k in ("json", "parquet", "toml")}
    # The clock waits for the page: the mission has not flown past Mode 6 when it comes.
    s = Session("--speed", "100", "--pause-when-alone", "--json", str(paths["json"]),
                "--telemetry",
                str(paths["parquet"]), "--save-commands", str(paths["toml"]))
    try:
        yield s, paths
    finally:
        s.kill()


def test_a_page_without_the_token_gets_403(driver, live):
    s, _ = live
    driver.get(s.url.split("?")[0])
    assert driver.find_element("tag name", "body").text.startswith("403: forbidden")


def test_a_page_of_another_origin_cannot_open_the_session_s_websocket(driver, live):
    """Even with the token: the session refuses the handshake (403) from another origin."""
    import http.server
    import threading

    s, _ = live
    page = b"<!DOCTYPE html><title>elsewhere</title>"

    class Elsewhere(http.server.BaseHTTPRequestHandler):
        def do_GET(self):
            self.send_response(200)
            self.send_header("Content-Type", "text/html")
            self.end_headers()
            self.wfile.write(page)

        def log_message(self, *args):
            pass

    # Threaded: a connection the browser opens ahead and leaves idle holds no other request.
    other = http.server.ThreadingHTTPServer(("127.0.0.1", 0), Elsewhere)
    other.daemon_threads = True
    threading.Thread(target=other.serve_forever, daemon=True).start()
    try:
        driver.get(f"http://127.0.0.1:{other.server_address[1]}/")
        driver.get_log("browser")
        outcome = driver.execute_async_script("""
            const done = arguments[1], ws = new WebSocket(arguments[0]);
            ws.onopen = () => done("open");
            ws.onclose = (e) => done("closed " + e.code);""", s.ws_url)
        logged = " ".join(e["message"] for e in driver.get_log("browser"))
    finally:
        other.shutdown()
    assert outcome == "closed 1006"
    assert "Unexpected response code: 403" in logged, logged


def test_the_live_page_commands_the_mission_and_the_log_flies_it_again(driver, live):
    s, paths = live
    driver.get(s.url)
    wait_for(driver, READY)
    assert driver.title.startswith("allsky live: default")
    wait_for(driver, "return window.allsky.session().t_s > 150")
    # Paused first: the commands below act at the boundary the clock stands at.
    driver.find_element("id", "g-pause").click()
    wait_for(driver, "return window.allsky.session().paused")
    assert driver.find_element("id", "g-pause").get_attribute("aria-pressed") == "true"
    # A tracker dropout, with the page's controls.
    driver.find_element("css selector", "#g-more summary").click()
    from selenium.webdriver.support.ui import Select

    Select(driver.find_element("id", "g-fault-kind")).select_by_value("tracker_dropout")
    driver.find_element("id", "g-fault-duration").send_keys("3")
    driver.find_element("id", "g-inject").click()
    said = wait_for(driver, "const t = document.getElementById('g-result').textContent;"
                            "return t.includes('inject tracker dropout') && t")
    assert "for 3 s (fault 0): at" in said
    # A new target, typed and uploaded.
    box = driver.find_element("id", "g-target")
    box.send_keys("Vega")
    driver.find_element("id", "g-upload").click()
    wait_for(driver, "return document.getElementById('g-result').textContent"
                     ".startsWith('new target Vega')")
    # window.allsky.command resolves with the entry once the page's journal holds it.
    entry, held = driver.execute_async_script("""
        const done = arguments[0];
        window.allsky.command({kind: "speed", speed: 200}).then((e) => done([e,
          window.allsky.journal().some((j) => JSON.stringify(j) === JSON.stringify(e))]));""")
    assert entry["kind"] == "ground_command" and entry["command"] == "speed" and held
    refused = driver.execute_async_script("""
        const done = arguments[0];
        window.allsky.command({kind: "proceed"}).then(() => done("resolved"),
                                                      (e) => done(e.message));""")
    assert refused == "not holding on a target: nothing to proceed from"
    commands = [e for e in driver.execute_script("return window.allsky.journal()")
                if e["kind"] == "ground_command"]
    assert [c["command"] for c in commands] == ["pause", "fault", "target", "speed"]
    assert len({c["t_s"] for c in commands}) == 1  # all at the boundary the clock stood at
    driver.find_element("id", "g-pause").click()  # resume
    wait_for(driver, "return !window.allsky.session().paused")
    # The event log shows them, and the page follows the newest row.
    log = wait_for(driver, "const t = document.getElementById('events').textContent;"
                           "return t.includes('Ground: speed x200') && t")
    assert "Ground: inject tracker dropout for 3 s (fault 0)" in log
    assert "Ground: new target Vega" in log
    assert driver.execute_script("return window.allsky.isFollowing()")
    # Reloaded, the page is a new client: it catches up from the journal.
    before = driver.execute_script("return window.allsky.journal()")
    driver.refresh()
    wait_for(driver, READY)
    again = driver.execute_script("return window.allsky.journal()")
    assert again[: len(before)] == before
    # Uploaded before Mode 6, the new target replaced the one to be flown.
    before_6 = commands[2]["t_s"] < min([r["start_s"] for r in driver.execute_script(
        "return window.allsky.timeline()") if r["mode"] == "6-1"] or [float("inf")])
    assert before_6
    assert driver.execute_script("return window.allsky.targets()[0].name") == "Vega"
    assert driver.execute_script("return window.allsky.range()[0]") == pytest.approx(0.1)
    # The end button, and its dialog.
    driver.find_element("id", "g-end").click()
    driver.find_element("id", "g-end-now").click()
    code, _, err = s.finish()
    assert code == 0, err
    wait_for(driver, "return document.getElementById('live-badge').textContent === 'ENDED'")
    assert "command log" in driver.find_element("id", "g-result").text
    live_summary = json.loads(paths["json"].read_text())
    final = driver.execute_script("return window.allsky.journal()")
    assert final == live_summary["events"]  # every entry reached the page
    # The saved session, flown again: the same summary and telemetry.
    again = {k: paths["json"].parent / f"again.{k}" for k in ("json", "parquet")}
    r = subprocess.run([*ALLSKY, "run", "--commands", str(paths["toml"]), "--json",
                        str(again["json"]), "--telemetry", str(again["parquet"]), "--quiet"],
                       capture_output=True, text=True, timeout=TIMEOUT_S, check=False)
    assert r.returncode == 0, r.stderr
    assert json.loads(again["json"].read_text()) == live_summary
    from allsky.apps.telemetry_files import read

    a, b = read(paths["parquet"])[0], read(again["parquet"])[0]
    assert a.shape == b.shape and np.array_equal(a.view(np.uint64), b.view(np.uint64))


def test_the_live_page_can_reach_nothing_but_its_session(driver, tmp_path):
    with_session = Session("--speed", "20")
    try:
        driver.get(with_session.url)
        wait_for(driver, READY)
        blocked = driver.execute_async_script("""
            const done = arguments[0];
            document.addEventListener("securitypolicyviolation",
                                      (e) => done(e.violatedDirective + " " + e.blockedURI));
            try { new WebSocket("ws://127.0.0.1:9/"); } catch (e) { done("threw " + e.name); }
            fetch("/?token=x").catch(() => {});""")
        assert blocked.startswith(("connect-src ws://127.0.0.1:9", "threw"))
    finally:
        with_session.kill()


def test_the_live_page_names_its_two_clocks_and_fits_720p(driver, tmp_path):
    """The session's clock and the recording's are named; the footer's play is hidden while
    the page follows live; a hint says to pause first; nothing overflows 1280x720."""
    s = Session("--speed", "50", "--pause-when-alone", "--json", str(tmp_path / "s.json"))
    try:
        driver.get(s.url)
        wait_for(driver, READY)
        wait_for(driver, "return window.allsky.session().t_s > 20")
        names = driver.execute_script(
            "return Array.from(document.querySelectorAll('.clock-name'))"
            ".filter((e) => e.offsetParent !== null).map((e) => e.textContent.trim());")
        assert names == ["live session", "review the recording"]
        assert driver.execute_script("return window.allsky.isFollowing()") is True
        assert driver.execute_script("return document.getElementById('btn-play').hidden")
        hint = driver.execute_script("return document.getElementById('g-pause-hint').textContent")
        assert "pause the live session first" in " ".join(hint.split())
        size = driver.execute_script("return [document.documentElement.scrollHeight, "
                                     "window.innerHeight, document.documentElement.scrollWidth, "
                                     "window.innerWidth]")
        assert size[0] <= size[1] and size[2] <= size[3], size
        driver.execute_script("window.allsky.seek(5)")  # reviewing: the footer's play is back
        assert not driver.execute_script("return document.getElementById('btn-play').hidden")
    finally:
        s.kill()


def test_a_warned_completion_is_amber_on_the_live_page(driver, tmp_path):
    """gyro-failure-to-target flown live: the badge is COMPLETE, AS JUDGED, never COMPLETE."""
    s = Session("gyro-failure-to-target", "--speed", "1000", "--pause-when-alone",
                "--json", str(tmp_path / "s.json"))
    try:
        driver.get(s.url)
        wait_for(driver, READY)
        wait_for(driver, "return window.allsky.session().status === 'complete'")
        badge = wait_for(driver, "const b = document.getElementById('live-badge'); "
                                 "return b.textContent === 'COMPLETE, AS JUDGED' && "
                                 "[b.className, b.title];")
        assert "judged" in badge[0] and "Mode 6-2 declared the vehicle on Sirius" in badge[1]
        wait_for(driver, "return document.getElementById('ending').className === 'judged'")
    finally:
        s.kill()
