"""Bad inputs and bad output paths, as a careless user gives them: how many are answered cleanly.

Run: ``python benchmarks/robustness_benchmark.py [--src SRC_DIR] [--verbose]``.

Every case is one whole ``allsky`` process (``python -m allsky``, with
``--src`` first on ``PYTHONPATH``), with a bound on its time. A case is
*clean* when the process ends within the bound with exit code 2 and exactly
one line ``allsky: error: ...`` on stderr (no traceback, no internal
error), and, for an output case, no device or FIFO was replaced by a file
and no temporary file is left. Cases a command accepts (exit 0 or 1) are
counted apart: the value was valid after all. The cases:

* every scenario key set to each of a dozen junk values (``config check
  --set``), and the values the emulator must refuse though they parse
  (a 1e12 kg tank, a fault after the longest mission, ...);
* every file the commands read (scenario, ``--disperse``, telemetry CSV and
  Parquet, ``--summary`` for plot and replay, ``step --from``, a campaign's
  manifest and results) given as a missing path, a directory, an empty
  file, junk bytes, text that is not UTF-8, a file past its size limit,
  ``/dev/zero``, a FIFO that is fed junk, a symbolic-link loop, and a
  valid file cut short;
* output options given a missing directory, a directory, a wrong suffix,
  ``/dev/full``, a device node and a FIFO made in a temporary directory,
  the path of another option, or an input's path;
* option values: ``--runs`` 0, -1, 1e9, 20000000, text; ``--workers`` 0;
  ``--kinds ,``; ``--scheduler ''``; ``--every 0``; and so on.

Prints the counts per group and in all (tried, clean, accepted, not clean)
and, with ``--verbose``, every case that was not clean.
"""

import argparse
import json
import os
import shutil
import stat
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

#: [s] Longest a case may take (a case that hangs is not clean).
BOUND_S = 120
JUNK_VALUES = ["nan", "inf", "-inf", "-1", "0", "1e308", '"x"', "[]", "[1, 2, 3, 4, 5]", "{}",
               "true", "99999999999999999999999"]


def _env(src):
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH",)}
    if src:
        env["PYTHONPATH"] = src
    return env


def run_case(argv, cwd, env, feed_fifo=None):
    """Run ``allsky argv``; (code, stderr) or (None, why) when it outlived the bound."""
    feeder = None
    if feed_fifo is not None:
        def feed():
            try:
                with open(feed_fifo, "wb") as f:
                    while True:
                        f.write(b"\x00junk" * 4096)
            except OSError:
                pass
        feeder = threading.Thread(target=feed, daemon=True)
        feeder.start()
    try:
        proc = subprocess.run([sys.executable, "-m", "allsky", *argv], cwd=cwd, env=env,
                              stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL,
                              stderr=subprocess.PIPE, timeout=BOUND_S, check=False)
    except subprocess.TimeoutExpired:
        return None, f"did not end within {BOUND_S} s"
    return proc.returncode, proc.stderr.decode("utf-8", "replace")


def clean(code, err) -> bool:
    lines = err.strip().splitlines()
    return (code == 2 and len(lines) == 1 and lines[0].startswith("allsky: error: ")
            and "Traceback" not in err)


def scenario_value_cases():
    """``config check --set KEY=VALUE`` for every scenario key and junk value."""
    sys.path.insert(0, os.environ.get("ALLSKY_SRC", ""))
    from allsky.config.schema import RULES

    for key in sorted(RULES):
        for value in JUNK_VALUES:
            yield f"set {key}={value}", ["config", "check", "--set", f"{key}={value}"]
    for text in ("jets.propellant_kg=1e12", "jets.propellant_kg=1e300",
                 'faults=[{kind="gyro_dead", axis="roll", start_s=1e9}]',
                 'faults=[{kind="gyro_dead", axis="roll", start_s=4500}]',
                 'faults=[{kind="nope"}]', "mission.seed=4294967296", "mission.frame_s=1e-9",
                 "mission.date_utc=2200-01-01T00:00:00Z", 'target.star="Nowhere"',
                 "dispersions.gyro.drift_deg_h={dist=\"normal\",sigma=-1}",
                 "dispersions.nope={dist=\"normal\",sigma=1}", "=1", "x", "gyro..drift=1"):
        yield f"set {text}", ["config", "check", "--set", text]


def option_cases():
    yield "runs 0", ["montecarlo", "--runs", "0"]
    yield "runs -1", ["montecarlo", "--runs", "-1"]
    yield "runs text", ["montecarlo", "--runs", "many"]
    yield "runs 1e9", ["compare", "--runs", "1e9"]
    yield "runs 1000000000", ["compare", "--runs", "1000000000"]
    yield "runs 20000000", ["montecarlo", "--runs", "20000000"]
    yield "workers 0", ["montecarlo", "--runs", "2", "--workers", "0"]
    yield "kinds ,", ["faults", "--kinds", ","]
    yield "modes ,", ["faults", "--modes", ","]
    yield "kinds unknown", ["faults", "--kinds", "gyro_dread"]
    yield "modes never flown", ["faults", "--modes", "hold"]
    yield "scheduler empty", ["montecarlo", "--runs", "2", "--scheduler", ""]
    yield "scheduler blank", ["montecarlo", "--runs", "2", "--scheduler", "  "]
    yield "every 0", ["step", "--every", "0"]
    yield "every nan", ["step", "--every", "nan"]
    yield "until unknown", ["step", "--until", "9", "--no-pause"]
    yield "resume without out", ["montecarlo", "--resume"]
    yield "resume empty dir", ["montecarlo", "--resume", "--out", "."]
    yield "no runs", ["montecarlo"]
    yield "sweep bad", ["compare", "--sweep", "amplitude_urad=a,b"]
    yield "sweep and methods", ["compare", "--sweep", "record_s=204.8", "--methods",
                                "legacy,dither"]
    yield "methods bad", ["compare", "--methods", "legacy"]
    yield "wheel beta 90", ["analyze", "--envelope", "--wheel-beta", "90"]
    yield "date bad", ["stars", "--date", "yesterday"]
    yield "unknown scenario", ["run", "no-such-scenario"]
    yield "config check bare", ["config", "check"]


def _write(path, data):
    Path(path).write_bytes(data)
    return str(path)


def reader_cases(work: Path, env):
    """Each reader given each kind of bad file."""
    valid = work / "valid"
    valid.mkdir()
    tlm, summ = valid / "t.csv", valid / "s.json"
    subprocess.run([sys.executable, "-m", "allsky", "run", "--quiet", "--telemetry", str(tlm),
                    "--json", str(summ), "--plots", str(valid / "figs")], env=env, check=True,
                   stdout=subprocess.DEVNULL, cwd=work)
    subprocess.run([sys.executable, "-m", "allsky", "step", "--no-pause", "--until", "2",
                    "--save-dir", str(valid / "states")], env=env, check=True,
                   stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, cwd=work)
    subprocess.run([sys.executable, "-m", "allsky", "montecarlo", "--runs", "2", "--workers",
                    "1", "--out", str(valid / "mc"), "--quiet"], env=env, check=True,
                   stdout=subprocess.DEVNULL, cwd=work)
    state = next((valid / "states").glob("*.npz"))
    readers = {
        "scenario": (lambda p: ["run", p], ".toml", b"[mission]\nseed = 3\n"),
        "--disperse": (lambda p: ["run", "--disperse", p], ".toml",
                       b'[dispersions]\n"gyro.drift_deg_h" = { dist = "normal", sigma = 0.1 }\n'),
        "telemetry csv (plot)": (lambda p: ["plot", p, "--out", "figs"], ".csv",
                                 tlm.read_bytes()),
        "telemetry csv (replay)": (lambda p: ["replay", p, "--html", "r.html"], ".csv",
                                   tlm.read_bytes()),
        "telemetry parquet": (lambda p: ["plot", p, "--out", "figs"], ".parquet", b"PAR1"),
        "--summary (plot)": (lambda p: ["plot", str(tlm), "--summary", p, "--out", "figs"],
                             ".json", summ.read_bytes()),
        "--summary (replay)": (lambda p: ["replay", str(tlm), "--summary", p, "--html",
                                          "r.html"], ".json", summ.read_bytes()),
        "--from": (lambda p: ["step", "--from", p, "--no-pause"], ".npz", state.read_bytes()),
    }
    limits = {".toml": 2**20, ".json": 16 * 2**20, ".npz": 64 * 2**20, ".csv": 2**30,
              ".parquet": 2**30}
    for name, (argv, suffix, good) in readers.items():
        kinds = {
            "missing": None, "directory": "dir", "empty": b"", "junk": os.urandom(700),
            "not UTF-8": b"\xff\xfe\xfa" + good[:200], "cut short": good[: len(good) // 2],
            "a JSON list": b"[1, 2, 3]", "deep nesting": b"[" * 100000,
            "past its size limit": "big", "/dev/zero": "zero", "a fed FIFO": "fifo",
            "a symlink loop": "loop",
        }
        for kind, content in kinds.items():
            d = work / f"r{abs(hash((name, kind)))}"
            d.mkdir()
            p = d / f"in{suffix}"
            fifo = None
            if content is None:
                pass
            elif content == "dir":
                p.mkdir()
            elif content == "big":
                with open(p, "wb") as f:
                    f.truncate(limits[suffix] + 1)  # sparse: costs nothing on disk
            elif content == "zero":
                p.symlink_to("/dev/zero")
            elif content == "fifo":
                os.mkfifo(p)
                fifo = p
            elif content == "loop":
                p.symlink_to(p)
            else:
                p.write_bytes(content)
            yield f"{name}: {kind}", argv(str(p)), d, fifo
    m = valid / "mc"
    for what, data in (("manifest junk", b"\x00junk"), ("manifest list", b"[]"),
                       ("results junk", b"run,seed\n1,x\n")):
        d = work / f"mc{abs(hash(what))}"
        shutil.copytree(m, d)
        (d / ("campaign.json" if what.startswith("manifest") else "runs.csv")).write_bytes(data)
        yield f"campaign {what}", ["montecarlo", "--resume", "--out", str(d), "--quiet"], work, \
            None


def output_cases(work: Path):
    """Output options given paths that cannot be, or must not be, written as files."""
    outs = {"run --json": ["run", "--json"], "run --telemetry": ["run", "--telemetry"],
            "run --html": ["run", "--html"], "run --plots": ["run", "--plots"],
            "analyze --plot": ["analyze", "--plot"], "stars --json": ["stars", "--json"],
            "montecarlo --out": ["montecarlo", "--runs", "2", "--workers", "1", "--out"]}
    for name, argv in outs.items():
        for kind in ("missing directory", "a directory", "wrong suffix", "/dev/full",
                     "a file as a directory", "its own input", "read-only directory"):
            d = work / f"o{abs(hash((name, kind)))}"
            d.mkdir()
            if kind == "missing directory":
                path = d / "no" / "x.csv"
            elif kind == "a directory":
                path = d
                if argv[-1] in ("--plots", "--out"):
                    continue  # a directory is what these take
            elif kind == "wrong suffix":
                if argv[-1] not in ("--telemetry", "--html", "--plot"):
                    continue
                path = d / "x.xyz"
            elif kind == "/dev/full":
                if argv[-1] in ("--plots", "--out"):
                    continue
                node = d / ("full" + {"--telemetry": ".csv", "--html": ".html",
                                      "--plot": ".png"}.get(argv[-1], ""))
                os.mknod(node, 0o666 | stat.S_IFCHR, os.stat("/dev/full").st_rdev)
                path = node
            elif kind == "a file as a directory":
                (d / "f").write_text("x")
                path = d / "f" / "x.csv"
            elif kind == "its own input":
                if argv[0] not in ("run",):
                    continue
                scen = d / "s.toml"
                scen.write_text("[mission]\nseed = 2\n")
                yield f"{name}: {kind}", ["run", str(scen), argv[-1], str(scen)], d, None
                continue
            else:
                ro = d / "ro"
                ro.mkdir()
                ro.chmod(0o555)
                if os.access(ro, os.W_OK):  # root writes anyway: not a bad path here
                    continue
                path = ro / "x.csv"
            yield f"{name}: {kind}", [*argv, str(path)], d, None
    for a, b in (("--json", "--telemetry"), ("--html", "--json"), ("--json", "--plots")):
        d = work / f"same{a}{b}"
        d.mkdir()
        path = str(d / ("x.html" if "--html" in (a, b) else "x.csv"))
        yield f"run {a} and {b} on one path", ["run", a, path, b, path], d, None


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--src", help="source tree to measure (put first on PYTHONPATH)")
    ap.add_argument("--verbose", action="store_true", help="print every case not clean")
    args = ap.parse_args(argv)
    src = os.path.abspath(args.src) if args.src else None
    if src:
        os.environ["ALLSKY_SRC"] = src
    env = _env(src)
    groups = {}
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix="allsky-robust-") as tmp:
        work = Path(tmp)
        cases = [("values", n, a, work, None) for n, a in scenario_value_cases()]
        cases += [("options", n, a, work, None) for n, a in option_cases()]
        cases += [("input files", n, a, d, f) for n, a, d, f in reader_cases(work, env)]
        cases += [("output paths", n, a, d, f) for n, a, d, f in output_cases(work)]
        for group, name, argv_, cwd, fifo in cases:
            code, err = run_case(argv_, cwd, env, fifo)
            ok = code is not None and clean(code, err)
            accepted = code in (0, 1) and "Traceback" not in err
            leftovers = [p for p in Path(cwd).rglob("*") if ".tmp" in p.name]
            g = groups.setdefault(group, {"tried": 0, "clean": 0, "accepted": 0, "not": [],
                                          "which": []})
            g["tried"] += 1
            if ok and not leftovers:
                g["clean"] += 1
            elif accepted and not leftovers:
                g["accepted"] += 1
                g["which"].append(name)
            else:
                g["not"].append((name, code, err.strip()[-300:], leftovers))
    total = {k: sum(g[k] if k != "not" else len(g[k]) for g in groups.values())
             for k in ("tried", "clean", "accepted", "not")}
    for group, g in groups.items():
        print(f"{group:<14} tried {g['tried']:>4}, refused cleanly {g['clean']:>4}, accepted "
              f"{g['accepted']:>4}, not clean {len(g['not']):>3}")
        if args.verbose:
            if group != "values":
                for name in g["which"]:
                    print(f"    accepted: {name}")
            for name, code, err, left in g["not"]:
                print(f"    {name}: exit {code}: {err!r}{' leftovers' if left else ''}")
    print(f"{'all':<14} tried {total['tried']:>4}, refused cleanly {total['clean']:>4}, "
          f"accepted {total['accepted']:>4}, not clean {total['not']:>3} "
          f"({time.perf_counter() - t0:.0f} s)")
    print(json.dumps(total))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
