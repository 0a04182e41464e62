"""Screenshots of the replay page for docs/replay.md: one per mode of the default mission.

Run from the repository root (needs chromium, chromedriver and selenium, as
tests/apps/test_replay_browser.py)::

    python docs/replay_screenshots.py [OUT_DIR]     # default: docs/img

Flies the default mission, writes its page, opens it in headless chromium at
1280x720 and saves ``replay_<mode>.png`` at a moment of each mode where the
mode's work shows (the times below are fractions of the mode's span).
"""

import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))

from allsky.apps import replay  # noqa: E402
from allsky.config import load_scenario  # noqa: E402
from allsky.sim.mission import run_mission  # noqa: E402

#: Where in each mode to look, as a fraction of its span: Mode 2 just before the star
#: enters the slit, Modes 4 and 5 half-way round, the others part-way.
WHEN = {"1": 0.35, "2": 0.5, "3": 0.5, "4": 0.45, "5": 0.45, "6-1": 0.25, "6-2": 0.3}


def main(out_dir):
    from test_replay_browser import new_driver

    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    cfg = load_scenario()
    m = run_mission(cfg)
    page = Path(tempfile.mkdtemp()) / "mission.html"
    replay.write_replay(page, m.telemetry(), m.summary(), cfg)
    driver = new_driver()
    try:
        driver.get(page.as_uri())
        for r in m.summary()["modes"]:
            f = WHEN.get(r["mode"], 0.5)
            driver.execute_script("window.allsky.seek(arguments[0])",
                                  r["start_s"] + f * (r["end_s"] - r["start_s"]))
            path = out_dir / f"replay_{r['mode'].replace('-', '_')}.png"
            if not driver.save_screenshot(str(path)):
                raise OSError(f"cannot write {path}")
            print(path)
    finally:
        driver.quit()


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else ROOT / "docs" / "img")
