"""The replay page in a real headless browser (Debian's chromium and chromedriver).

One browser for the module: the page of the default mission is opened
once; each test drives it through ``window.allsky``, the keyboard and the
buttons, the way a user does, and compares what it shows with the
telemetry, the journal and the summary. Other missions (three targets,
the historical faults, a wheel vehicle) are opened in the same browser.
Without the browser the tests are skipped, naming the command that
installs it; the accessibility check loads axe-core from the npm registry
on the test side (never from the page), and is skipped, naming the
command, where npm or the network is missing.
"""

import itertools
import json
import math
import os
import shutil
import subprocess
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
ROOT = Path(__file__).resolve().parents[2]
#: Where the tests keep axe-core (``npm install --prefix AXE_DIR axe-core``).
AXE_DIR = Path(os.environ.get("ALLSKY_TEST_CACHE", Path.home() / ".cache" / "allsky-tests")) / "axe"
AXE_INSTALL = f"npm install --prefix {AXE_DIR} axe-core"
#: Records the texts canvases draw (font, place, extent; the first 20000 from the page's load,
#: offscreen backgrounds included), set before the page loads.
CANVAS_HOOK = """
(() => {
  const P = CanvasRenderingContext2D.prototype, fill = P.fillText;
  window.__canvasTexts = [];
  P.fillText = function (text, x, y) {
    if (window.__canvasTexts.length < 20000) {
      const m = this.measureText(text), tr = this.getTransform(), dpr = window.devicePixelRatio || 1;
      window.__canvasTexts.push({canvas: this.canvas.id, text: String(text), font: this.font,
        left: (tr.a * x + tr.e) / dpr - m.actualBoundingBoxLeft,
        right: (tr.a * x + tr.e) / dpr + m.actualBoundingBoxRight,
        top: (tr.d * y + tr.f) / dpr - m.actualBoundingBoxAscent,
        bottom: (tr.d * y + tr.f) / dpr + m.actualBoundingBoxDescent,
        width: this.canvas.width / dpr, height: this.canvas.height / dpr});
    }
    return fill.apply(this, arguments);
  };
})();"""


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
    set_viewport(driver, *VIEWPORT)
    return driver


def set_viewport(driver, width, height, scale=1.0):
    """A window of ``width`` x ``height`` CSS px at ``scale`` device pixels per px (zoom)."""
    driver.execute_cdp_cmd("Emulation.setDeviceMetricsOverride",
                           {"width": width, "height": height, "deviceScaleFactor": scale,
                            "mobile": False})


@pytest.fixture(scope="module")
def flown(saved_states):
    m = saved_states["mission"]
    return m.telemetry(), m.summary(), m.cfg


@pytest.fixture(scope="module")
def browser(flown, tmp_path_factory):
    """One browser for the module, and the default mission's page."""
    table, summary, cfg = flown
    path = tmp_path_factory.mktemp("replay") / "mission.html"
    replay.write_replay(path, table, summary, cfg, scenario=replay.describe_scenario())
    driver = new_driver()
    try:
        driver.execute_cdp_cmd("Page.addScriptToEvaluateOnNewDocument", {"source": CANVAS_HOOK})
        driver.get(path.as_uri())
        driver.logs = {"browser": driver.get_log("browser"),
                       "performance": driver.get_log("performance")}
        yield driver, path
    finally:
        driver.quit()


@pytest.fixture
def page(browser):
    """The default mission's page, at 1280x720 (opened again if a test left it)."""
    driver, path = browser
    set_viewport(driver, *VIEWPORT)
    if driver.current_url != path.as_uri():
        open_page(driver, path)
    return driver, path


def open_page(driver, path):
    """Open a page and check that it loads without a console message."""
    driver.get(path.as_uri())
    assert js(driver, "return window.allsky.ready") is True
    logs = driver.get_log("browser")
    assert [e for e in logs if e["level"] in ("SEVERE", "WARNING")] == [], logs


#: Missions flown for the tests beside the default: scenario and overrides.
MISSIONS = {
    "three": (ROOT / "docs" / "examples" / "three_targets.toml", []),
    "stuck_jet": ("stuck-jet-roll-calibration", []),
    "mariner4": ("mariner4-star-hopping", []),
    "voyager1": ("voyager1-wrong-star", []),
    "gyro_failure": ("gyro-failure-to-target", ["target.hold_s=300"]),
    "dust": ("mariner4-dust-glints", []),
    "free_flyer": ("shuttle-free-flyer", []),
    "sunset": ("shuttle-free-flyer-sunset", []),
    "wheels": (None, ['actuators.kind="wheels"', "wheels.max_momentum_n_m_s=6"]),
    "hold": (None, ["target.hold_s=300"]),
    # Jupiter inside the window on the Mariner cards' date: the tracker locks it in Mode 2
    "jupiter": ("shuttle-free-flyer", ["mission.date_utc=2026-11-28T00:00:00Z",
                                       "star_tracker.magnitude_window=[-2.5,-0.3]"]),
}


@pytest.fixture(scope="module")
def missions(tmp_path_factory):
    """``missions(name)``: (telemetry, summary, cfg, page path), each flown once."""
    from allsky.config import load_scenario
    from allsky.sim.mission import Mission

    cache, folder = {}, tmp_path_factory.mktemp("missions")

    def get(name):
        if name not in cache:
            scenario, overrides = MISSIONS[name]
            cfg = load_scenario(scenario, overrides)
            m = Mission(cfg)
            m.run()
            path = replay.write_replay(folder / f"{name}.html", m.telemetry(), m.summary(), cfg,
                                       scenario=replay.describe_scenario(scenario, overrides))
            cache[name] = (m.telemetry(), m.summary(), cfg, path)
        return cache[name]

    return get


@pytest.fixture
def other(browser, missions):
    """``other(name)``: open that mission's page in the module's browser; its data."""
    driver, _ = browser

    def go(name):
        table, summary, cfg, path = missions(name)
        set_viewport(driver, *VIEWPORT)
        open_page(driver, path)
        return driver, table, summary, cfg

    return go


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


def first_row_after(table, t_s):
    """[s] The first telemetry row written after ``t_s``: the first of a mode begun then."""
    t = table[:, INDEX["time"]]
    return float(t[0] if t_s <= t[0] else t[np.searchsorted(t, t_s, side="right")])


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
    _press(driver, "]")  # into Mode 3: its first row
    state = js(driver, "return window.allsky.state()")
    assert state["t_s"] == pytest.approx(first_row_after(table, starts[2]))
    assert state["mode"] == "3"
    _press(driver, "[", "[")
    state = js(driver, "return window.allsky.state()")
    assert state["t_s"] == pytest.approx(max(t0, first_row_after(table, starts[0])))
    assert state["mode"] == "1"
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
    _press(driver, "?")  # help is a dialog that takes the focus; Escape closes it
    assert js(driver, "return document.getElementById('help').open") is True
    assert js(driver, "return document.getElementById('help').contains("
                      "document.activeElement)") is True
    _press(driver, Keys.ESCAPE)
    assert js(driver, "return document.getElementById('help').open") is False


def test_buttons_events_and_playback(page, flown):
    driver, _ = page
    table, summary, _ = flown
    starts = [r["start_s"] for r in summary["modes"]]
    js(driver, "window.allsky.seek(arguments[0])", starts[3] + 5.0)
    driver.find_element("id", "btn-next").click()
    state = js(driver, "return window.allsky.state()")
    assert (state["t_s"], state["mode"]) == (pytest.approx(first_row_after(table, starts[4])),
                                             "5")
    driver.find_element("id", "btn-prev").click()
    state = js(driver, "return window.allsky.state()")
    assert (state["t_s"], state["mode"]) == (pytest.approx(first_row_after(table, starts[3])),
                                             "4")
    driver.find_element("id", "btn-fwd").click()
    assert js(driver, "return window.allsky.state().t_s") == pytest.approx(
        first_row_after(table, starts[3]) + 10.0)
    # An event of the log jumps to its time.
    item = driver.find_elements("css selector", "#events li button")[5]
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


def test_several_targets_show_the_one_flown(other):
    """Three targets (reacquire): in the second target's Mode 6-2 the page shows that one."""
    driver, _, summary, _ = other("three")
    names = [t["name"] for t in summary["targets"]]
    flights = [r for r in summary["modes"] if r["mode"] == "6-2"]
    assert len(flights) == len(names) == 3
    got = js(driver, """return arguments[0].map((t) => window.allsky.seek(t));""",
             [0.5 * (r["start_s"] + r["end_s"]) for r in flights])
    assert [(s["mode"], s["target"]) for s in got] == [("6-2", n) for n in names]
    assert [t["name"] for t in js(driver, "return window.allsky.targets()")] == names
    line = js(driver, "return document.getElementById('registers-line').textContent")
    assert f"reg. 24 ({names[2]})" in line


# -- wrong today: each compared with the telemetry, the journal and the summary ----------

def row_of(t, row_t_s):
    """The row whose time the page reports as ``row_t_s`` (exact to the millisecond)."""
    return int(np.argmin(np.abs(t - row_t_s)))


def _times(table, n=60):
    """``n`` telemetry row times spread over the record, and the last."""
    t = table[:, INDEX["time"]]
    return [float(t[i]) for i in np.linspace(0, len(t) - 1, n).astype(int)]


def test_body_rates_are_the_telemetry_in_deg_s(page, flown):
    """state() gives the true body rates in deg/s (1.498 deg/s at 243 s); the gyro box what
    the gyros output, in deg/s."""
    driver, _ = page
    table, _, _ = flown
    times = _times(table) + [243.0]
    got = js(driver, """return arguments[0].map((t) => { const s = window.allsky.seek(t);
        return [s.row_t_s, s.body_rate_deg_s, Array.from(document.querySelectorAll(
        '[data-box="1"] text')).map((e) => e.textContent)]; });""", times)
    t = table[:, INDEX["time"]]
    for row_t, rates, lines in got:
        r = row_of(t, row_t)
        want = np.degrees(table[r, [INDEX["rate_x"], INDEX["rate_y"], INDEX["rate_z"]]])
        # the page carries rates to 1 arcsec/s (the schema's scale): 0.5/3600 deg/s at most
        assert [rates[a] for a in AXES] == pytest.approx(want, abs=0.5 / 3600 + 1e-12)
        shown = [float(x.split()[1].replace("\u2212", "-").rstrip("°/s")) for x in lines[-3:]]
        gyro = table[r, [INDEX["gyro_roll"], INDEX["gyro_pitch"], INDEX["gyro_yaw"]]] / 3600.0
        # the page carries the outputs to 0.01 arcsec/s; the box shows 0.001 deg/s
        assert shown == pytest.approx(gyro, abs=0.0005 + 0.005 / 3600)
    assert got[-1][1]["roll"] == pytest.approx(1.498, abs=0.001)


def test_true_error_to_the_target_is_the_truth(page, flown):
    """The truth readouts follow the true_error column; the end is the summary's 8.7 arcsec.

    The 3-D view's own angle, from the attitude quaternion (rounded to 1e-5 per part),
    agrees within what that rounding allows: 2 |dq| <= 2 * 2 * 0.5e-5 rad = 4.1 arcsec.
    """
    driver, _ = page
    table, summary, _ = flown
    got = js(driver, """return arguments[0].map((t) => { const s = window.allsky.seek(t);
        const c = document.getElementById('vehicle');
        return [s.row_t_s, s.true_error_arcsec, +c.dataset.toTargetArcsec,
                document.getElementById('truth-error').textContent]; });""", _times(table))
    t = table[:, INDEX["time"]]
    quaternion_bound = math.degrees(2 * 2 * 0.5e-5) * 3600
    for row_t, truth, from_q, text in got:
        want = table[row_of(t, row_t), INDEX["true_error"]]
        assert truth == pytest.approx(want, abs=0.05 + 1e-9)
        assert from_q == pytest.approx(want, abs=quaternion_bound + 0.05)
        number = float(text.split(": ")[1][:-1])
        assert number == pytest.approx(want if text.endswith("\u2033") else want / 3600,
                                       abs=0.051 if text.endswith("\u2033") else 0.0006)
    end = summary["end"]["true_pointing_error_arcsec"]
    assert got[-1][1] == pytest.approx(end, abs=0.05)
    assert f"{end:.1f}\u2033" in got[-1][3] and end < 10.0


def test_mode_steps_land_inside_each_new_mode(other):
    """Three targets: ] steps to every mode begun, into its first row; [ steps back."""
    from selenium.webdriver.common.keys import Keys

    driver, table, summary, _ = other("three")
    t = table[:, INDEX["time"]]
    # Modes that hold at least one row (reacquire has none: its step is the next mode's).
    expected = []
    for r in summary["modes"]:
        land = first_row_after(table, r["start_s"])
        if land <= t[-1] and r["end_s"] >= land and (not expected or expected[-1][0] < land):
            expected.append((land, r["mode"]))
    assert len(summary["modes"]) == 20 and len(expected) == 18  # two hand-overs of no duration
    _press(driver, Keys.HOME)
    seen = []
    for _ in expected[1:]:
        _press(driver, "]")
        s = js(driver, "return window.allsky.state()")
        seen.append((s["t_s"], s["mode"]))
    assert seen == [(pytest.approx(a), m) for a, m in expected[1:]]
    for a, m in reversed(expected[:-1]):
        _press(driver, "[")
        s = js(driver, "return window.allsky.state()")
        assert (s["t_s"], s["mode"]) == (pytest.approx(a), m)


def _journal_star(journal, t_s):
    star = None
    for e in journal:
        if e["kind"] == "star_lock" and e["t_s"] <= t_s + 1e-9:
            star = e["star"]
    return star


def test_the_tracker_names_the_star_in_the_slit(other):
    """Voyager 1: at 150 s the slit holds Canopus, not the star finally locked."""
    driver, table, summary, _ = other("voyager1")
    assert summary["locked_star"] == "Rigil Kentaurus"
    times = [150.0] + _times(table, 80) + [e["t_s"] + 0.05 for e in summary["events"]
                                           if e["kind"] == "star_lock"]
    got = js(driver, """return arguments[0].map((t) => { const s = window.allsky.seek(t);
        return [s.t_s, s.tracker_star, document.getElementById('vehicle').dataset.star,
                Array.from(document.querySelectorAll('[data-box="105"] text')).map(
                  (e) => e.textContent).join(' ')]; });""", times)
    for t_s, star, drawn, box in got:
        want = _journal_star(summary["events"], t_s)
        assert star == want and drawn == (want or "")
        if want:
            assert want[:12] in box
    assert got[0][1] == "Canopus" and "Rigil" not in got[0][3]


def test_the_wheel_vehicle_draws_its_wheels(other):
    """The wheels' box shows the momentum per axis and the unloading, as recorded."""
    driver, table, _, _ = other("wheels")
    assert js(driver, "return document.querySelector('[data-box=\"39\"]').textContent"
              ).startswith("Reaction wheels")
    unloading = table[:, INDEX["unloading"]]
    rows = list(np.flatnonzero(unloading > 0)[::40][:8]) + list(
        np.flatnonzero(unloading == 0)[::400][:8])
    t = table[:, INDEX["time"]]
    got = js(driver, """return arguments[0].map((t) => { window.allsky.seek(t);
        const g = document.querySelector('[data-box="39"]');
        return [g.dataset.unloading, Array.from(g.querySelectorAll('text')).map(
          (e) => e.textContent), g.querySelectorAll('circle').length]; });""",
             [float(t[r]) for r in rows])
    assert len(rows) > 8
    for r, (flag, lines, circles) in zip(rows, got):
        assert flag == ("true" if unloading[r] else "false")
        h = [float(x.split()[1].replace("\u2212", "-")) for x in lines[-3:]]
        want = table[r, [INDEX["wheel_h_x"], INDEX["wheel_h_y"], INDEX["wheel_h_z"]]]
        assert h == pytest.approx(want, abs=0.005 + 1e-4)
        assert circles == 0  # no jets drawn firing on a wheel vehicle


# -- the ending, the faults, the warnings ----------------------------------------------

ENDING = """const s = window.allsky.seek(arguments[0]), e = document.getElementById('ending');
    return [s, e.hidden, e.textContent, document.getElementById('mode-badge').dataset.status,
            document.getElementById('mode-now').textContent];"""


def test_a_complete_mission_ends_with_its_banner(page, flown):
    driver, _ = page
    table, summary, _ = flown
    t1 = float(table[-1, INDEX["time"]])
    state, hidden, _, badge, _ = js(driver, ENDING, t1 - 1.0)
    assert state["status"] == "flying" and hidden and badge == "flying"
    state, hidden, text, badge, _ = js(driver, ENDING, t1)
    end = summary["end"]
    assert state["status"] == "complete" and not hidden and badge == "complete"
    assert f"Mission complete on {end['target']}" in text
    assert f"true error {end['true_pointing_error_arcsec']:.1f}\u2033" in text
    assert f"propellant used {end['propellant_kg']:.3f} kg" in text
    assert js(driver, "return document.title").startswith("allsky replay: default \u2014 complete")


def test_an_aborted_mission_shows_when_and_why(other):
    driver, table, summary, _ = other("stuck_jet")
    abort = next(e for e in summary["events"] if e["kind"] == "abort")
    reason = summary["abort_reason"]
    assert abort["reason"] == reason
    state, hidden, _, badge, _ = js(driver, ENDING, abort["t_s"] - 1.0)
    assert state["status"] == "flying" and hidden
    state, hidden, text, badge, now = js(driver, ENDING, float(table[-1, INDEX["time"]]))
    assert state["status"] == "aborted" and not hidden and badge == "aborted"
    assert reason in text and reason in now  # the full reason, nowhere cut
    assert js(driver, "return document.getElementById('status-badge').textContent") == "ABORTED"
    rows = js(driver, "return window.allsky.events().filter((e) => e.kind === 'abort')")
    assert [(r["t_s"], r["reason"]) for r in rows] == [(abort["t_s"], f"aborted: {reason}")]
    assert js(driver, "return document.querySelectorAll('#strip-marks .end-mark.aborted')"
                      ".length") == 1
    assert "ABORTED" in js(driver, "return document.title")


def _journal_faults(journal, t_s):
    """Indices of the faults acting at ``t_s`` by the journal: begun, not yet ended."""
    active = {}
    for e in journal:
        if e["kind"] == "fault" and e["t_s"] <= t_s + 1e-9:
            active[e["fault"]] = e["active"]
    return sorted(k for k, on in active.items() if on)


@pytest.mark.parametrize("name", ["mariner4", "stuck_jet"])
def test_faults_show_in_the_log_the_traces_and_the_blocks(other, name):
    """Each fault: a row of the log, a band on the strip, its block marked while it acts."""
    driver, table, summary, _ = other(name)
    faults = [e for e in summary["events"] if e["kind"] == "fault"]
    onsets = [e for e in faults if e["active"]]
    assert onsets
    rows = js(driver, "return window.allsky.events().filter((e) => e.kind === 'fault')")
    assert [(r["t_s"], r["text"]) for r in rows] == [
        (e["t_s"], f"fault: {e['text']} {'begins' if e['active'] else 'ends'}") for e in faults]
    assert js(driver, "return document.querySelectorAll('#strip-marks .fault-band').length") \
        == len(onsets)
    times = sorted({round(e["t_s"] + d, 3) for e in faults for d in (-0.5, 0.05, 1.0)}
                   | set(_times(table, 20)))
    got = js(driver, """return arguments[0].map((t) => { const s = window.allsky.seek(t);
        return [s.t_s, s.faults_active, Array.from(document.querySelectorAll('[data-box]'))
          .filter((g) => g.dataset.fault).map((g) => g.dataset.box)]; });""", times)
    acting = set()
    for t_s, active, marked in got:
        want = _journal_faults(summary["events"], t_s)
        assert sorted(active) == sorted(summary["faults"][k]["kind"] for k in want), t_s
        # The block the vocabulary names: tracker 105 for the glints and dropouts, the
        # roll jets' couple 39 for the stuck jet.
        boxes = {b for k in want for b in replay.fault_boxes(summary["faults"][k])}
        assert set(marked) == boxes, t_s
        acting |= boxes
    assert acting == ({"105"} if name == "mariner4" else {"39"})


def test_warnings_show_where_they_happen(other):
    """The gyro failure's warnings: rows of the log at the time each names, marks on the strip."""
    driver, _, summary, _ = other("gyro_failure")
    assert len(summary["warnings"]) == 2
    rows = js(driver, "return window.allsky.events().filter((e) => e.kind === 'warning')")
    assert [r["text"] for r in rows] == summary["warnings"]
    declared = next(r["end_s"] for r in summary["modes"] if r["mode"] == "6-2")
    # at the exact frame the mode ended (the record's time, not a telemetry row's)
    assert [r["t_s"] for r in rows] == [declared] * 2
    assert js(driver, "return document.querySelectorAll('#strip-marks .warning-mark').length") \
        == 2


def test_truth_beside_belief_in_the_hold(other):
    """In the hold CPU 22 judges near zero while the true error grows: both are shown."""
    driver, table, summary, _ = other("hold")
    hold = next(r for r in summary["modes"] if r["mode"] == "hold")
    t = table[:, INDEX["time"]]
    got = js(driver, """return arguments[0].map((t) => { const s = window.allsky.seek(t);
        return [s.row_t_s, s.true_error_arcsec, document.getElementById('truth-error').textContent,
                document.getElementById('truth-cpu').textContent]; });""",
             [hold["start_s"] + 5.0, hold["end_s"]])
    values = []
    for row_t, truth, text, cpu in got:
        r = row_of(t, row_t)
        want = table[r, INDEX["true_error"]]
        assert truth == pytest.approx(want, abs=0.05)
        assert f"{want:.1f}\u2033" in text
        judged = math.hypot(table[r, INDEX["error_pitch"]], table[r, INDEX["error_yaw"]])
        assert cpu == f"CPU 22 judges {judged:.1f}\u2033"
        values.append(want)
    assert values[1] > values[0]


def test_register_23_is_flagged_where_far_from_the_truth(page, other):
    """Voyager 1's roll scale factor (6.14, truth 0.9985) is flagged; the default's none."""
    driver, _ = page
    assert js(driver, "window.allsky.seek(1e9); return document.getElementById("
                      "'registers-line').dataset.flagged") == "0"
    driver, _, summary, _ = other("voyager1")
    flagged = js(driver, """window.allsky.seek(1e9); return Array.from(document.querySelectorAll(
        '#registers-line td.far-off')).map((c) => c.textContent);""")
    assert summary["calibration"]["scale_factor"]["roll"] > 6.0
    assert any(c.startswith("\u26a0SFr 6.14") for c in flagged)


def test_who_when_what(page, flown):
    driver, _ = page
    _, _, cfg = flown
    title = js(driver, "return document.title")
    line = js(driver, "return document.getElementById('mission-line').textContent")
    assert title == "allsky replay: default \u2014 complete \u2014 2026-11-22, seed 1"
    assert line.startswith("default Default allsky mission") and "seed 1" in line
    assert cfg.mission.date_utc.strftime("%Y-%m-%d %H:%M:%S") in line


# -- legible and usable by everyone ----------------------------------------------------

TEXTS = """
const out = [], vw = window.innerWidth;
const visible = (el) => { const st = getComputedStyle(el);
  return st.visibility !== 'hidden' && st.display !== 'none' && el.getClientRects().length; };
const inHidden = (el) => el.closest('[hidden], dialog:not([open]), .sr-only');
for (const el of document.querySelectorAll('body *')) {
  if (inHidden(el) || !visible(el)) continue;
  const own = Array.from(el.childNodes).some((n) => n.nodeType === 3 && n.textContent.trim());
  if (!own) continue;
  let px = parseFloat(getComputedStyle(el).fontSize);
  if (el instanceof SVGElement) px *= el.getScreenCTM().a;
  const r = el.getBoundingClientRect();
  out.push({tag: el.tagName, id: el.id, text: el.textContent.trim().slice(0, 40), px: px,
            left: r.left, right: r.right});
}
return out;"""

CLIPPED = """
const out = [];
for (const el of document.querySelectorAll('body *')) {
  const st = getComputedStyle(el);
  if (el.closest('[hidden], dialog:not([open]), .sr-only') || st.display === 'none') continue;
  const hides = (v) => v === 'hidden' || v === 'clip';
  if (st.textOverflow === 'ellipsis' || ((hides(st.overflowX) && el.scrollWidth > el.clientWidth + 1)
      || (hides(st.overflowY) && el.scrollHeight > el.clientHeight + 1)))
    out.push([el.tagName, el.id, el.className.baseVal === undefined ? el.className : '',
              el.textContent.trim().slice(0, 40)]);
}
// Box texts of the diagram inside their boxes.
for (const g of document.querySelectorAll('[data-box]')) {
  const b = g.querySelector('rect').getBoundingClientRect();
  for (const t of g.querySelectorAll('text')) {
    if (!t.textContent || t.getAttribute('visibility') === 'hidden') continue;
    const r = t.getBoundingClientRect();
    if (r.left < b.left - 0.5 || r.right > b.right + 0.5 || r.top < b.top - 0.5 || r.bottom > b.bottom + 0.5)
      out.push(['box', g.dataset.box, t.textContent]);
  }
}
return out;"""

VIEWPORTS = {"1280x720": (1280, 720, 1.0), "1920x1080": (1920, 1080, 1.0),
             "800x900": (800, 900, 1.0), "200% of 1280x720": (640, 360, 2.0)}


@pytest.mark.parametrize("viewport", list(VIEWPORTS))
@pytest.mark.parametrize("name", ["default", "stuck_jet"])
def test_text_is_legible_and_nothing_is_clipped(browser, missions, flown, viewport, name):
    """At least 11 px everywhere at 1280x720; nothing cut at any of the four windows."""
    driver, default_path = browser
    width, height, scale = VIEWPORTS[viewport]
    set_viewport(driver, width, height, scale)
    path = default_path if name == "default" else missions(name)[3]
    open_page(driver, path)
    table = flown[0] if name == "default" else missions(name)[0]
    t = table[:, INDEX["time"]]
    for t_s in (float(t[len(t) // 3]), float(t[-1])):
        js(driver, "window.allsky.seek(arguments[0])", t_s)
        texts = js(driver, TEXTS)
        assert len(texts) > 100
        small = [x for x in texts if x["px"] < 11 - 1e-6]
        if viewport == "1280x720" or scale > 1:
            assert small == [], small[:5]
        assert js(driver, CLIPPED) == []
        canvas = js(driver, "return window.__canvasTexts")
        assert {c["canvas"] for c in canvas} >= {"vehicle", "sky", ""}  # "": backgrounds
        assert len(canvas) > 60
        for c in canvas:
            px = float(next(w for w in c["font"].split() if w.endswith("px"))[:-2])
            assert px >= 11, c
            assert -0.5 <= c["left"] and c["right"] <= c["width"] + 0.5, c
            assert -0.5 <= c["top"] and c["bottom"] <= c["height"] + 0.5, c
        doc = js(driver, "return [document.documentElement.scrollWidth, window.innerWidth]")
        assert doc[0] <= doc[1]  # no sideways scrolling of the page (the diagram scrolls alone)
    one_column = js(driver, """const r = (id) => document.getElementById(id).getBoundingClientRect();
        return [r('diagram-panel').left, r('traces-panel').left, r('events-panel').left];""")
    if width < 1172:
        assert max(one_column) - min(one_column) < 1  # one scrolling column
    else:
        assert one_column[1] > one_column[0] + 500


def test_keyboard_and_screen_readers(page):
    """Event rows are buttons; the scrubber and mode changes are spoken; canvases described."""
    from selenium.webdriver.common.keys import Keys

    driver, _ = page
    state = js(driver, "return window.allsky.seek(470)")
    assert state["mode"] == "4"
    assert js(driver, "return document.getElementById('scrub').getAttribute('aria-valuetext')") \
        == "470.0 s, Mode 4"
    js(driver, "window.allsky.seek(700)")
    assert js(driver, "return document.getElementById('announce').textContent").startswith(
        "Mode 5")
    for cid in ("vehicle", "sky", "traces", "diagram"):
        label = js(driver, f"return document.getElementById('{cid}').getAttribute('aria-label')")
        assert "700.0 s" in label
    button = driver.find_elements("css selector", "#events li button")[3]
    event = js(driver, "return window.allsky.events()[3]")
    js(driver, "arguments[0].focus()", button)
    button.send_keys(Keys.ENTER)
    assert js(driver, "return window.allsky.state().t_s") == pytest.approx(event["t_s"])
    tags = js(driver, "return Array.from(document.querySelectorAll('#events li')).map("
                      "(li) => li.firstElementChild.tagName)")
    assert set(tags) == {"BUTTON"}


def _axe_source():
    """axe-core's script, from the npm registry into AXE_DIR (never loaded by the page)."""
    path = AXE_DIR / "node_modules" / "axe-core" / "axe.min.js"
    if not path.exists():
        npm = shutil.which("npm")
        if not npm:
            pytest.skip(f"axe-core missing and npm not installed; install with: {AXE_INSTALL}")
        try:
            subprocess.run([npm, "install", "--prefix", str(AXE_DIR), "axe-core", "--no-audit",
                            "--no-fund", "--loglevel=error"], check=True, timeout=180,
                           capture_output=True)
        except (subprocess.SubprocessError, OSError):
            pass
        if not path.exists():
            pytest.skip(f"could not install axe-core (no network?); install with: {AXE_INSTALL}")
    return path.read_text(encoding="utf-8")


AXE_RUN = """const done = arguments[arguments.length - 1];
window.axe.run(document, {resultTypes: ['violations']}).then(
  (r) => done(r.violations.map((v) => ({id: v.id, impact: v.impact, help: v.help,
    nodes: v.nodes.slice(0, 3).map((n) => n.target.join(' '))}))),
  (e) => done([{id: 'axe failed', impact: 'critical', help: String(e), nodes: []}]));"""


@pytest.mark.parametrize("name", ["default", "stuck_jet"])
def test_axe_finds_no_serious_violation(browser, missions, name):
    """axe-core (npm, injected by the test) at 1280x720, mid-flight, at the end, help open."""
    source = _axe_source()
    driver, default_path = browser
    set_viewport(driver, *VIEWPORT)
    open_page(driver, default_path if name == "default" else missions(name)[3])
    driver.set_script_timeout(60)
    js(driver, source)
    for setup in ("window.allsky.seek(400)", "window.allsky.seek(1e9)",
                  "document.getElementById('btn-help').click()"):
        js(driver, setup)
        found = driver.execute_async_script(AXE_RUN)
        bad = [v for v in found if v["impact"] in ("serious", "critical")]
        assert bad == [], bad
    js(driver, "document.getElementById('help').close()")


BOX_LINES = """return Array.from(document.querySelectorAll(`[data-box="${arguments[0]}"] text`))
    .map((e) => e.textContent);"""


def _deg_s(text):
    """The signed rates [deg/s] a box's value lines show ("1   +0.000°/s")."""
    import re

    return [float(x) for x in re.findall(r"([+\u2212-]?\d+\.\d+)\u00b0/s",
                                          text.replace("\u2212", "-"))]


def test_the_gyro_box_reads_the_gyros_and_the_vehicle_strip_the_truth(other):
    """The dead pitch gyro: box 1 shows its output, 0; the vehicle strip the true tumble.

    Each box is held to the telemetry column it claims (gyro_* for box 1, rate_* for the
    vehicle 100); in Mode 6-2 of gyro-failure-to-target the two differ by 19 deg/s.
    """
    driver, table, summary, _ = other("gyro_failure")
    t = table[:, INDEX["time"]]
    onset = next(e["t_s"] for e in summary["events"] if e["kind"] == "fault" and e["active"])
    declared = next(r["end_s"] for r in summary["modes"] if r["mode"] == "6-2")
    times = list(np.linspace(onset + 1.0, declared, 6)) + [float(t[len(t) // 4])]
    sides = js(driver, "return Array.from(document.querySelectorAll('[data-box]'))"
                       ".map((g) => [g.dataset.box, g.dataset.side]);")
    assert dict(sides)["100"] == "truth" and dict(sides)["1"] == "belief"
    assert {s for _, s in sides} == {"belief", "truth"}
    tumbled = False
    for when in times:
        state = js(driver, "return window.allsky.seek(arguments[0])", float(when))
        r = row_of(t, state["row_t_s"])
        gyro_deg_s = [table[r, INDEX[f"gyro_{a}"]] / 3600.0 for a in AXES]
        true_deg_s = [math.degrees(table[r, INDEX[f"rate_{c}"]]) for c in "xyz"]
        box1 = _deg_s(" ".join(js(driver, BOX_LINES, "1")))
        strip = [float(x) for x in " ".join(js(driver, BOX_LINES, "100")).replace(
            "\u2212", "-").split("true body rates (r p y)")[1].split("\u00b0/s")[0].split()]
        assert box1 == pytest.approx(gyro_deg_s, abs=2e-3), when
        assert strip == pytest.approx(true_deg_s, abs=2e-3), when
        assert [state["gyro_output_deg_s"][a] for a in AXES] == pytest.approx(gyro_deg_s,
                                                                               abs=1e-4)
        if when > onset:
            assert box1[1] == 0.0  # the dead gyro says nothing
        tumbled |= abs(strip[1]) > 10.0
    assert tumbled  # while the vehicle pitches at over 10 deg/s


def test_a_warned_completion_is_amber_with_the_first_warning(other):
    """gyro-failure-to-target completes as the sequencer judged: amber, never green."""
    driver, table, summary, _ = other("gyro_failure")
    first = summary["warnings"][0]
    state, hidden, text, badge, now = js(driver, ENDING, float(table[-1, INDEX["time"]]))
    assert state["status"] == "complete" and not hidden and badge == "complete"
    ending = js(driver, "const e = document.getElementById('ending'); return [e.className, "
                        "getComputedStyle(e).borderTopColor, document.getElementById("
                        "'status-badge').textContent, document.getElementById('mode-badge')"
                        ".dataset.tone, document.getElementById('mode-badge').style.background];")
    assert ending[0] == "judged" and ending[1] == "rgb(154, 103, 0)"
    assert ending[2] == "COMPLETE, AS JUDGED" and ending[3] == "amber"
    assert ending[4] == "rgb(154, 103, 0)"
    assert "as the sequencer judged" in text and first in text and first in now
    assert js(driver, "return document.querySelectorAll('#strip-marks .end-mark.judged')"
                      ".length") == 1
    assert "complete, as the sequencer judged" in js(driver, "return document.title")


#: Every packaged scenario, by its name in MISSIONS ("default": the module's own page).
PACKAGED = {"default": "default", "gyro-failure-to-target": "gyro_failure",
            "mariner4-dust-glints": "dust", "mariner4-star-hopping": "mariner4",
            "stuck-jet-roll-calibration": "stuck_jet", "voyager1-wrong-star": "voyager1",
            "shuttle-free-flyer": "free_flyer", "shuttle-free-flyer-sunset": "sunset"}
OVERLAPS = """const out = [];
for (const id of ["vehicle", "sky"]) {
  const t = window.__canvasTexts.filter((c) => c.canvas === id);
  for (let i = 0; i < t.length; i++) for (let j = i + 1; j < t.length; j++) {
    const a = t[i], b = t[j];
    if (Math.min(a.right, b.right) - Math.max(a.left, b.left) > 0.5
        && Math.min(a.bottom, b.bottom) - Math.max(a.top, b.top) > 0.5) out.push([id, a.text, b.text]);
  }
}
return [out, window.__canvasTexts.filter((c) => c.canvas === "vehicle").length,
        window.__canvasTexts.filter((c) => c.canvas === "sky").length];"""


def test_packaged_scenarios_are_what_the_labels_test_flies():
    from allsky.config.faults import packaged_scenarios

    assert set(PACKAGED) == {e["name"] for e in packaged_scenarios()}


@pytest.mark.parametrize("viewport", ["1280x720", "800x900", "1920x1080"])
def test_no_two_labels_overlap_in_the_3d_view_and_the_sky_map(browser, missions, flown,
                                                              viewport):
    """Every packaged scenario at five times: zero overlapping label boxes on either canvas."""
    driver, default_path = browser
    set_viewport(driver, *VIEWPORTS[viewport])
    try:
        for scenario, name in PACKAGED.items():
            path = default_path if name == "default" else missions(name)[3]
            table = flown[0] if name == "default" else missions(name)[0]
            open_page(driver, path)
            t = table[:, INDEX["time"]]
            for k in range(5):
                t_s = float(t[min(len(t) - 1, (2 * k + 1) * len(t) // 10)])
                js(driver, "window.__canvasTexts = []; window.allsky.seek(arguments[0]);", t_s)
                overlaps, n_vehicle, n_sky = js(driver, OVERLAPS)
                assert overlaps == [], (scenario, t_s, overlaps)
                assert n_vehicle >= 5 and n_sky >= 3, (scenario, t_s)  # the labels drawn
    finally:
        set_viewport(driver, *VIEWPORT)


@pytest.mark.parametrize("viewport", ["1280x720", "800x900", "1920x1080"])
def test_the_header_keeps_its_height_through_the_modes(browser, flown, viewport):
    """No panel moves at a mode change: the header is as tall in every mode flown."""
    driver, path = browser
    set_viewport(driver, *VIEWPORTS[viewport])
    try:
        open_page(driver, path)
        _, summary, _ = flown
        heights = js(driver, """return arguments[0].map((t) => { window.allsky.seek(t);
            return [document.getElementById('mode-row').getBoundingClientRect().height,
                    document.getElementById('panels').getBoundingClientRect().top]; });""",
                     [0.5 * (r["start_s"] + r["end_s"]) for r in summary["modes"]])
        assert len({round(h, 1) for h, _ in heights}) == 1, heights
        assert len({round(top, 1) for _, top in heights}) == 1, heights
    finally:
        set_viewport(driver, *VIEWPORT)


def test_the_3d_view_and_the_sky_map_enlarge_in_place_at_720p(page, flown):
    """At 1280x720 the views are small; v and m enlarge each over the page, Esc puts it back."""
    from selenium.webdriver.common.keys import Keys

    driver, _ = page
    size = """const r = document.getElementById(arguments[0]).getBoundingClientRect();
        return [r.width, r.height];"""
    t = flown[0][:, INDEX["time"]]
    js(driver, "window.allsky.seek(arguments[0])", float(t[len(t) // 2]))
    small = {c: js(driver, size, c) for c in ("vehicle", "sky")}
    body = driver.find_element("tag name", "body")
    for key, canvas, panel in (("v", "vehicle", "vehicle-panel"), ("m", "sky", "sky-panel")):
        body.send_keys(key)
        big = js(driver, size, canvas)
        assert big[0] >= 1100 and big[1] >= 500, (canvas, small[canvas], big)
        assert js(driver, f"return document.getElementById('{panel}').classList"
                          ".contains('enlarged')")
        assert js(driver, f"return +document.getElementById('{canvas}').dataset"
                          ".labelsDropped") == 0  # room for every label
        body.send_keys(Keys.ESCAPE)
        assert js(driver, size, canvas) == small[canvas]
    button = driver.find_element("css selector", 'button.enlarge[data-panel="sky-panel"]')
    button.click()
    assert button.get_attribute("aria-pressed") == "true"
    button.click()
    assert js(driver, size, "sky") == small["sky"]


@pytest.mark.parametrize("width", [1123, 1171, 1172])
def test_the_page_fits_a_notebook_frame(page, width):
    """A notebook's inline frame (about 1123 px): nothing cut on the right at any width."""
    driver, path = page
    set_viewport(driver, width, 860)
    try:
        open_page(driver, path)
        sizes = js(driver, "return [document.documentElement.scrollWidth, window.innerWidth]")
        assert sizes[0] <= sizes[1], sizes
        columns = js(driver, """const r = (id) => document.getElementById(id).getBoundingClientRect();
            return [r('diagram-panel').left, r('traces-panel').left];""")
        assert (columns[1] > columns[0] + 500) == (width >= 1172)
    finally:
        set_viewport(driver, *VIEWPORT)


def test_words_never_written_read_not_calibrated(other):
    """shuttle-free-flyer-sunset aborts in Mode 5: its yaw words read not calibrated."""
    driver, _, summary, _ = other("sunset")
    assert summary["status"] == "aborted" and summary["modes"][-1]["mode"] == "5"
    cells = js(driver, """window.allsky.seek(1e9); return Array.from(document.querySelectorAll(
        '#registers-line tr:first-child td.word')).map((c) => [c.textContent, c.title]);""")
    shown = {text.split()[0].lstrip("\u26a0"): (text, title) for text, title in cells}
    for word in ("SFy", "y\u2192p", "y\u2192r"):
        assert shown[word][0] == f"{word} not cal.", shown[word]
        assert "not calibrated (Mode 5 aborted)" in shown[word][1]
    for word in ("SFr", "r\u2192p", "r\u2192y"):
        assert "not cal." not in shown[word][0] and "not calibrated" not in shown[word][1]


def test_the_sky_map_draws_the_moon_and_the_planets_where_they_are(other):
    """``bodies(t_s)`` against the ephemeris; the locked planet ringed as the star in the slit."""
    from allsky.vehicle import bodies, sky

    driver, table, summary, cfg = other("jupiter")
    lock = next(e for e in summary["events"] if e["kind"] == "star_lock")
    assert lock["star"] == "Jupiter"
    for t_s in (0.0, lock["t_s"] + 1.0, float(table[-1, INDEX["time"]])):
        got = {b["name"]: b for b in js(driver, "return window.allsky.bodies(arguments[0])", t_s)}
        assert set(got) == set(bodies.BODIES)
        for name, b in got.items():
            r = bodies.from_earth_km(name, cfg.mission.date_utc, t_s)
            ra, dec = sky.unit_to_radec(r)
            u, v = sky.radec_to_unit(ra, dec), sky.radec_to_unit(b["ra_deg"], b["dec_deg"])
            assert math.degrees(math.acos(min(1.0, float(u @ v)))) < 0.002, (name, t_s)
        assert got["Jupiter"]["in_window"] and got["Jupiter"]["flown"]
        assert not got["Venus"]["in_window"]
    state = js(driver, "return window.allsky.seek(arguments[0])", lock["t_s"] + 1.0)
    assert state["tracker_star"] == "Jupiter"
    assert "slit on Jupiter" in driver.find_element("id", "sky").get_attribute("aria-label")
    logs = driver.get_log("browser")
    assert [e for e in logs if e["level"] in ("SEVERE", "WARNING")] == [], logs
