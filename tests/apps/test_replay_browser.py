"""The replay page in a real headless browser (Debian's chromium and chromedriver).

One browser for the module: the page of the default mission is opened
once; each test drives it through ``window.allsky``, the keyboard and the
buttons, the way a user does. Without the browser the tests are skipped,
naming the command that installs it.
"""

import itertools
import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from allsky.apps import replay
from allsky.apps.plots import mode_name
from allsky.hardware.wiring import SELECTORS
from allsky.sim.telemetry import INDEX, switch_closed

INSTALL = "apt-get update && apt-get install -y chromium chromium-driver"
CHROMIUM = shutil.which("chromium") or "/usr/bin/chromium"
CHROMEDRIVER = shutil.which("chromedriver") or "/usr/bin/chromedriver"
#: Chromium flags: headless, and nothing of its own that reaches the network.
BROWSER_FLAGS = ("--headless=new", "--no-sandbox", "--disable-gpu",
                 "--disable-background-networking", "--disable-component-update",
                 "--disable-sync", "--disable-quic")
VIEWPORT = (1280, 720)
AXES = ("roll", "pitch", "yaw")


def new_driver():
    """A headless chromium through selenium at 1280x720, logging console and network."""
    webdriver = pytest.importorskip("selenium.webdriver", reason=f"selenium missing: pip "
                                    f"install selenium; browser: {INSTALL}")
    from selenium.webdriver.chrome.service import Service

    if not (Path(CHROMIUM).exists() and Path(CHROMEDRIVER).exists()):
        pytest.skip(f"chromium/chromedriver not installed; install with: {INSTALL}")
    opts = webdriver.ChromeOptions()
    opts.binary_location = CHROMIUM
    for flag in BROWSER_FLAGS:
        opts.add_argument(flag)
    opts.set_capability("goog:loggingPrefs", {"browser": "ALL", "performance": "ALL"})
    driver = webdriver.Chrome(service=Service(CHROMEDRIVER), options=opts)
    driver.execute_cdp_cmd("Emulation.setDeviceMetricsOverride",
                           {"width": VIEWPORT[0], "height": VIEWPORT[1],
                            "deviceScaleFactor": 1, "mobile": False})
    return driver


@pytest.fixture(scope="module")
def flown(saved_states):
    m = saved_states["mission"]
    return m.telemetry(), m.summary(), m.cfg


@pytest.fixture(scope="module")
def page(flown, tmp_path_factory):
    table, summary, cfg = flown
    path = tmp_path_factory.mktemp("replay") / "mission.html"
    replay.write_replay(path, table, summary, cfg)
    driver = new_driver()
    try:
        driver.get(path.as_uri())
        driver.logs = {"browser": driver.get_log("browser"),
                       "performance": driver.get_log("performance")}
        yield driver, path
    finally:
        driver.quit()


def js(driver, script, *args):
    return driver.execute_script(script, *args)


def expected_state(table, row):
    # A selector (S7/S8) is never open: it joins one contact, the row's s7_s8 axis.
    closed = {f"S{k}": k in SELECTORS or bool(switch_closed(table, k)[row])
              for k in range(1, 20)}
    return {"mode": mode_name(table[row, INDEX["mode"]]), "switches": closed,
            "selector": AXES[int(table[row, INDEX["s7_s8"]])],
            "counters_pulses": {k: int(table[row, INDEX[f"counter{k}"]])
                                for k in ("14", "16", "18")}}


def test_page_loads_without_console_errors(page):
    driver, _ = page
    assert js(driver, "return window.allsky.ready") is True
    logs = driver.logs["browser"] + driver.get_log("browser")
    assert [e for e in logs if e["level"] in ("SEVERE", "WARNING")] == []


def test_no_request_leaves_the_page(page):
    driver, path = page
    js(driver, "window.allsky.seek(500); window.allsky.play(200);")
    driver.execute_async_script("setTimeout(arguments[0], 300)")
    js(driver, "window.allsky.pause()")
    messages = [json.loads(e["message"])["message"]
                for e in driver.logs["performance"] + driver.get_log("performance")]
    urls = {m["params"]["request"]["url"] for m in messages
            if m["method"] == "Network.requestWillBeSent"}
    assert urls == {path.as_uri()}


def test_state_is_the_telemetry_in_every_mode(page, flown):
    driver, _ = page
    table, _, _ = flown
    t = table[:, INDEX["time"]]
    code = table[:, INDEX["mode"]]
    cuts = np.r_[0, np.flatnonzero(np.diff(code) != 0) + 1, len(t)]
    rows = []
    for a, b in itertools.pairwise(cuts):
        rows += [a, (a + b) // 2, b - 1, min(a + 3, b - 1)]
    # Rows where the switches or selector change, and the row before each.
    for name in ("switches", "s7_s8"):
        ch = np.flatnonzero(np.diff(table[:, INDEX[name]]) != 0)[:40]
        rows += list(ch) + list(ch + 1)
    got = js(driver, "return arguments[0].map((t) => window.allsky.seek(t))",
             [float(t[r]) for r in rows])
    for r, state in zip(rows, got):
        want = expected_state(table, r)
        assert {k: state[k] for k in want} == want, f"row {r}, t = {t[r]}"
        assert state["t_s"] == pytest.approx(t[r])
    # Between two rows the page shows the earlier one.
    state = js(driver, "return window.allsky.seek(arguments[0])", float(t[500] + 0.04))
    assert state["counters_pulses"] == expected_state(table, 500)["counters_pulses"]
    modes_seen = {expected_state(table, r)["mode"] for r in rows}
    assert modes_seen == {r["mode"] for r in flown[1]["modes"]}
    assert {s["target"] for s in got} == {flown[1]["target"]["star"]}


DRAWN = """
    const q = (sel) => Array.from(document.querySelectorAll(sel));
    return {switches: Object.fromEntries(q('[data-switch]').map(
              (g) => ['S' + g.dataset.switch, g.dataset.closed === 'true'])),
            selectors: Object.fromEntries(q('[data-selector]').map(
              (g) => ['S' + g.dataset.selector, g.dataset.axis]))};"""


def test_the_diagram_draws_what_state_reports(page, flown):
    """Each drawn on/off switch as state() has it; S7 and S8 on the selected contact."""
    driver, _ = page
    table, summary, _ = flown
    t = table[:, INDEX["time"]]
    changes = np.flatnonzero(np.diff(table[:, INDEX["s7_s8"]]) != 0)
    rows = [len(t) // 3, int(changes[0]), int(changes[0]) + 1, int(changes[-1]) + 1]
    rows += [int(np.searchsorted(t, 0.5 * (r["start_s"] + r["end_s"])))
             for r in summary["modes"]]
    for r in rows:
        state = js(driver, "return window.allsky.seek(arguments[0])", float(t[r]))
        drawn = js(driver, DRAWN)
        assert drawn["switches"] == {k: v for k, v in state["switches"].items()
                                     if int(k[1:]) not in SELECTORS}
        assert drawn["selectors"] == {f"S{k}": state["selector"] for k in SELECTORS}
        assert state["selector"] == AXES[int(table[r, INDEX["s7_s8"]])]


def test_seek_takes_numbers_and_ignores_the_rest(page, flown):
    driver, _ = page
    table, _, _ = flown
    t0, t1 = float(table[0, INDEX["time"]]), float(table[-1, INDEX["time"]])
    got = js(driver, """
        const a = window.allsky, out = [];
        a.seek(300);
        for (const v of ["abc", NaN, undefined, Infinity, -Infinity, {}]) out.push(a.seek(v).t_s);
        out.push(a.seek("412.5").t_s, a.seek(-5).t_s, a.seek(1e9).t_s, a.seek(" 7 ").t_s);
        return out;""")
    assert got == pytest.approx([300.0] * 6 + [412.5, t0, t1, 7.0], abs=1e-6)
    logs = driver.get_log("browser")
    assert [e for e in logs if e["level"] == "SEVERE"] == []


def _press(driver, *keys, shift=False):
    """Type ``keys`` on the page (nothing focused), with Shift held if asked."""
    from selenium.webdriver.common.action_chains import ActionChains
    from selenium.webdriver.common.keys import Keys

    js(driver, "document.activeElement && document.activeElement.blur()")
    chain = ActionChains(driver)
    if shift:
        chain.key_down(Keys.SHIFT)
    for k in keys:
        chain.send_keys(k)
    if shift:
        chain.key_up(Keys.SHIFT)
    chain.perform()


def test_keyboard_shortcuts(page, flown):
    from selenium.webdriver.common.keys import Keys

    driver, _ = page
    table, summary, _ = flown
    t0, t1 = float(table[0, INDEX["time"]]), float(table[-1, INDEX["time"]])
    starts = [r["start_s"] for r in summary["modes"]]
    js(driver, "window.allsky.seek(arguments[0])", 200.0)
    _press(driver, Keys.ARROW_RIGHT)
    assert js(driver, "return window.allsky.state().t_s") == pytest.approx(201.0)
    _press(driver, Keys.ARROW_LEFT, shift=True)
    assert js(driver, "return window.allsky.state().t_s") == pytest.approx(191.0)
    _press(driver, "]")
    assert js(driver, "return window.allsky.state().t_s") == pytest.approx(starts[2])
    _press(driver, "[", "[")
    assert js(driver, "return window.allsky.state().t_s") == pytest.approx(max(t0, starts[0]))
    _press(driver, Keys.END)
    assert js(driver, "return window.allsky.state().t_s") == pytest.approx(t1)
    _press(driver, Keys.HOME, ".")
    assert js(driver, "return window.allsky.state().t_s") == pytest.approx(
        float(table[1, INDEX["time"]]))
    _press(driver, " ")
    assert js(driver, "return window.allsky.isPlaying()") is True
    _press(driver, " ")
    assert js(driver, "return window.allsky.isPlaying()") is False
    assert js(driver, "return window.allsky.state().t_s") > t0
    _press(driver, "?")
    assert js(driver, "return document.getElementById('help').hidden") is False
    _press(driver, Keys.ESCAPE)
    assert js(driver, "return document.getElementById('help').hidden") is True


def test_buttons_events_and_playback(page, flown):
    driver, _ = page
    _, summary, _ = flown
    starts = [r["start_s"] for r in summary["modes"]]
    js(driver, "window.allsky.seek(arguments[0])", starts[3] + 5.0)
    driver.find_element("id", "btn-next").click()
    assert js(driver, "return window.allsky.state().t_s") == pytest.approx(starts[4])
    driver.find_element("id", "btn-prev").click()
    assert js(driver, "return window.allsky.state().t_s") == pytest.approx(starts[3])
    driver.find_element("id", "btn-fwd").click()
    assert js(driver, "return window.allsky.state().t_s") == pytest.approx(starts[3] + 10.0)
    # An event of the log jumps to its time.
    item = driver.find_elements("css selector", "#events li")[5]
    event = js(driver, "return window.allsky.events()[5]")
    item.click()
    assert js(driver, "return window.allsky.state().t_s") == pytest.approx(event["t_s"])
    # Play at x200 for a moment: the clock moves forward, then pause holds it.
    driver.find_element("id", "speed").send_keys("×200")
    before = js(driver, "return window.allsky.state().t_s")
    driver.find_element("id", "btn-play").click()
    driver.execute_async_script("setTimeout(arguments[0], 400)")
    driver.find_element("id", "btn-play").click()
    after = js(driver, "return window.allsky.state().t_s")
    assert after > before
    driver.execute_async_script("setTimeout(arguments[0], 100)")
    assert js(driver, "return window.allsky.state().t_s") == after


def test_page_fits_1280x720(page):
    driver, _ = page
    sizes = js(driver, """
        const r = (id) => document.getElementById(id).getBoundingClientRect();
        return {doc: [document.documentElement.scrollWidth, document.documentElement.scrollHeight],
                panels: ['diagram', 'vehicle', 'sky', 'traces', 'events'].map((id) => {
                  const b = r(id); return [b.left, b.top, b.right, b.bottom]; })};""")
    assert sizes["doc"] == list(VIEWPORT)
    for left, top, right, bottom in sizes["panels"]:
        assert 0 <= left < right <= VIEWPORT[0] and 0 <= top < bottom <= VIEWPORT[1]
        assert right - left > 150 and bottom - top > 90


def test_screenshots_in_every_mode(page, flown, tmp_path):
    driver, _ = page
    _, summary, _ = flown
    for r in summary["modes"]:
        js(driver, "window.allsky.seek(arguments[0])", 0.5 * (r["start_s"] + r["end_s"]))
        out = tmp_path / f"replay_{r['mode']}.png"
        assert driver.save_screenshot(str(out))
        assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and out.stat().st_size > 20_000
    logs = driver.get_log("browser")
    assert [e for e in logs if e["level"] == "SEVERE"] == []


def test_several_targets_show_the_one_flown(page, tmp_path):
    """Three targets (reacquire): in the second target's Mode 6-2 the page shows that one."""
    from allsky.config import load_scenario
    from allsky.sim.mission import Mission

    driver, default_path = page
    scenario = Path(__file__).resolve().parents[2] / "docs" / "examples" / "three_targets.toml"
    cfg = load_scenario(scenario, ["target.hold_s=0"])
    m = Mission(cfg)
    summary = m.run()
    path = replay.write_replay(tmp_path / "three.html", m.telemetry(), summary, cfg)
    try:
        driver.get(path.as_uri())
        names = [t["name"] for t in summary["targets"]]
        flights = [r for r in summary["modes"] if r["mode"] == "6-2"]
        assert len(flights) == len(names) == 3
        got = js(driver, """return arguments[0].map((t) => window.allsky.seek(t));""",
                 [0.5 * (r["start_s"] + r["end_s"]) for r in flights])
        assert [(s["mode"], s["target"]) for s in got] == [("6-2", n) for n in names]
        assert [t["name"] for t in js(driver, "return window.allsky.targets()")] == names
        line = js(driver, "return document.getElementById('registers-line').textContent")
        assert f"reg. 24 ({names[2]})" in line
        logs = driver.get_log("browser")
        assert [e for e in logs if e["level"] in ("SEVERE", "WARNING")] == []
    finally:
        driver.get(default_path.as_uri())
