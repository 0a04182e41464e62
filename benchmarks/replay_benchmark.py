"""Replay page: time to write it, its size, and how it runs in headless chromium.

Run from the repository root::

    python benchmarks/replay_benchmark.py [--out DIR] [--repeat N]

Measures, for the default mission (telemetry every 10 frames) and for the same mission
recorded at every frame (``--set mission.telemetry_every_frames=1``, 10x the rows):

* writing the page after the mission [s] (target <= 3 s) and its size [MB] (<= 6 MB);
* in headless chromium at 1280x720 (the flags of tests/apps/test_replay_browser.py):
  page interactive after load [s] (navigation start to ``window.allsky.ready``,
  target <= 2 s); one ``seek`` and redraw [ms] (the script's own time, and to the
  next painted frame; target <= 50 ms); frame times during playback at x50 [ms]
  (requestAnimationFrame intervals and redraw times over 5 s of playback).

Prints a table and writes the figures as JSON (``--out``). Timing only: the
default test run checks none of these numbers.
"""

import argparse
import json
import statistics
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests" / "apps"))

from allsky.apps import replay
from allsky.config import load_scenario
from allsky.sim.mission import run_mission

#: Playback measured at this speed for this long [s of wall time].
SPEED, PLAY_S = 50, 5.0

FRAMES_JS = """
const done = arguments[arguments.length - 1], speed = arguments[0], play_s = arguments[1];
const gaps = [], draws = [];
let last = null;
const t0 = performance.now();
window.allsky.seek(window.allsky.range()[0] + 10);
window.allsky.play(speed);
function tick(now) {
  if (last !== null) { gaps.push(now - last); draws.push(window.allsky.timing.lastDrawMs); }
  last = now;
  if (now - t0 < play_s * 1000) requestAnimationFrame(tick);
  else { window.allsky.pause(); done({gaps: gaps, draws: draws}); }
}
requestAnimationFrame(tick);
"""

SEEK_JS = """
const done = arguments[arguments.length - 1];
const times = arguments[0], script = [], painted = [];
let k = 0;
function next() {
  if (k >= times.length) { done({script: script, painted: painted}); return; }
  const a = performance.now();
  window.allsky.seek(times[k]);
  script.push(performance.now() - a);
  requestAnimationFrame(() => { painted.push(performance.now() - a); k += 1; setTimeout(next, 0); });
}
next();
"""


def pct(values, q):
    values = sorted(values)
    return values[min(len(values) - 1, round(q / 100 * (len(values) - 1)))]


def measure(out_dir, repeat=3, overrides=(), prefix=""):
    cfg = load_scenario(overrides=list(overrides))
    m = run_mission(cfg)
    table, summary = m.telemetry(), m.summary()
    path = Path(out_dir) / f"mission{prefix}.html"
    write_s = []
    for _ in range(repeat):
        a = time.perf_counter()
        replay.write_replay(path, table, summary, cfg,
                            scenario=replay.describe_scenario(None, overrides))
        write_s.append(time.perf_counter() - a)
    res = {"rows": len(table), "write_s": min(write_s),
           "size_mb": path.stat().st_size / 1e6}

    from test_replay_browser import new_driver

    driver = new_driver()
    try:
        driver.set_script_timeout(60)
        load = []
        for _ in range(repeat):
            driver.get("about:blank")
            driver.get(path.as_uri())
            load.append(driver.execute_script("return window.allsky.readyAt_ms") / 1000)
        res["interactive_s"] = min(load)
        t0, t1 = driver.execute_script("return window.allsky.range()")
        times = [t0 + (t1 - t0) * k / 60 for k in range(61)]
        seek = driver.execute_async_script(SEEK_JS, times)
        res["seek_script_ms_median"] = statistics.median(seek["script"])
        res["seek_script_ms_p95"] = pct(seek["script"], 95)
        res["seek_painted_ms_median"] = statistics.median(seek["painted"])
        res["seek_painted_ms_p95"] = pct(seek["painted"], 95)
        frames = driver.execute_async_script(FRAMES_JS, SPEED, PLAY_S)
        gaps, draws = frames["gaps"], frames["draws"]
        res["play_x50_frames"] = len(gaps)
        res["play_x50_frame_ms_median"] = statistics.median(gaps)
        res["play_x50_frame_ms_p95"] = pct(gaps, 95)
        res["play_x50_frame_ms_max"] = max(gaps)
        res["play_x50_redraw_ms_median"] = statistics.median(draws)
        res["play_x50_redraw_ms_p95"] = pct(draws, 95)
    finally:
        driver.quit()
    return {prefix + k: v for k, v in res.items()}


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", help="directory for the page and replay_benchmark.json")
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args()
    out = Path(args.out) if args.out else Path(tempfile.mkdtemp(prefix="replay_bench_"))
    out.mkdir(parents=True, exist_ok=True)
    res = measure(out, args.repeat)
    res.update(measure(out, args.repeat, ["mission.telemetry_every_frames=1"], "every_frame_"))
    for k, v in res.items():
        print(f"{k:<40} {v:.3f}" if isinstance(v, float) else f"{k:<40} {v}")
    (out / "replay_benchmark.json").write_text(json.dumps(res, indent=2) + "\n")
    print(f"page and figures in {out}")


if __name__ == "__main__":
    main()
