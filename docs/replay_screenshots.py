"""Screenshots of the replay page for docs/replay.md: each mode, the ending, a fault, an abort.

Run from the repository root (needs chromium, chromedriver and selenium, as
tests/apps/test_replay_browser.py)::

    python docs/replay_screenshots.py [OUT_DIR]     # default: docs/img

Flies the default mission, writes its page, opens it in headless chromium at
1280x720 and saves ``replay_<mode>.png`` at a moment of each mode where the
mode's work shows (the times below are fractions of the mode's span), and
``replay_end.png`` at its end; then ``replay_fault.png`` (Mariner 4's dropout in
Mode 5) and ``replay_aborted.png`` (the stuck roll jet's abort).
"""

import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests" / "apps"))

from allsky.apps import replay  # noqa: E402
from allsky.config import load_scenario  # noqa: E402
from allsky.sim.mission import run_mission  # noqa: E402

#: Where in each mode to look, as a fraction of its span: Mode 2 just before the star
#: enters the slit, Modes 4 and 5 half-way round, the others part-way.
WHEN = {"1": 0.35, "2": 0.5, "3": 0.5, "4": 0.45, "5": 0.45, "6-1": 0.25, "6-2": 0.3}


#: Other missions: (file name, scenario, time [s] or None for the end).
OTHERS = (("replay_fault.png", "mariner4-star-hopping", 1002.0),
          ("replay_aborted.png", "stuck-jet-roll-calibration", None))


def _page(scenario, folder):
    cfg = load_scenario(scenario)
    m = run_mission(cfg)
    page = Path(folder) / f"{scenario or 'default'}.html"
    replay.write_replay(page, m.telemetry(), m.summary(), cfg,
                        scenario=replay.describe_scenario(scenario))
    return m, page


def _shot(driver, path):
    if not driver.save_screenshot(str(path)):
        raise OSError(f"cannot write {path}")
    print(path)


def main(out_dir):
    from test_replay_browser import new_driver

    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    folder = tempfile.mkdtemp()
    m, page = _page(None, folder)
    driver = new_driver()
    try:
        driver.get(page.as_uri())
        for r in m.summary()["modes"]:
            f = WHEN.get(r["mode"], 0.5)
            driver.execute_script("window.allsky.seek(arguments[0])",
                                  r["start_s"] + f * (r["end_s"] - r["start_s"]))
            _shot(driver, out_dir / f"replay_{r['mode'].replace('-', '_')}.png")
        driver.execute_script("window.allsky.seek(1e9)")
        _shot(driver, out_dir / "replay_end.png")
        for name, scenario, t_s in OTHERS:
            _, page = _page(scenario, folder)
            driver.get(page.as_uri())
            driver.execute_script("window.allsky.seek(arguments[0])", 1e9 if t_s is None else t_s)
            _shot(driver, out_dir / name)
    finally:
        driver.quit()


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else ROOT / "docs" / "img")
