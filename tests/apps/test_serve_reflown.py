"""A live session re-flies from its saved log, bit for bit (hypothesis, through ``allsky serve``).

A test client commands a running ``allsky serve`` at arbitrary wall times --
faults of random kinds, fields and durations, their clearing, pauses and
speeds, a new target -- and ends with *proceed* and *end* sent together, so
that they may act at one mission time. The session's summary and telemetry
must equal those of ``allsky run --commands`` on the log it saved: what the
wall clock decided (when each command landed) is in the log, and nothing
else of it is in the flight.
"""

import asyncio
import json
import subprocess

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from tests.apps.test_serve import ALLSKY, TIMEOUT_S, Client, serving
from tests.sim.test_command_logs import FAULTS

#: What the client may send during the flight, besides the ending.
COMMANDS = st.one_of(
    FAULTS.map(lambda f: {"kind": "fault", **f}),
    st.just({"kind": "clear_fault", "fault": 0}),
    st.just({"kind": "pause"}),
    st.just({"kind": "resume"}),
    st.sampled_from((50.0, 200.0, 400.0)).map(lambda v: {"kind": "speed", "speed": v}),
    st.sampled_from(("Vega", "Sirius", "Arcturus")).map(lambda s: {"kind": "target",
                                                                   "star": s}),
)
#: [s] wall time the client waits before each command.
WAITS = st.floats(0.0, 0.6)


async def _fly(s, plan):
    c = await Client.connect(s.ws_url)
    await c.until(lambda c: c.hello is not None)
    paused = False
    for wait, command in plan:
        await asyncio.sleep(wait)
        answer = await c.command(command)
        assert answer["type"] in ("done", "refused"), answer
        if answer["type"] == "done" and command["kind"] in ("pause", "resume"):
            paused = command["kind"] == "pause"
    if paused:
        await c.command({"kind": "resume"})
    # proceed and end together: no wait for the first's answer before the second
    for ident, kind in ((9001, "proceed"), (9002, "end")):
        await c.ws.send_str(json.dumps({"type": "command", "id": ident,
                                        "command": {"kind": kind}}))
    await c.until(lambda c: False)
    await c.close()


@pytest.fixture(scope="module", autouse=True)
def _compiled():
    """The loops compiled and cached first: a server's warm-up then loads, not compiles."""
    from allsky.sim.warm_up import LOOPS, warm_up

    warm_up(LOOPS)


@settings(max_examples=3, deadline=None, derandomize=True,
          suppress_health_check=[HealthCheck.too_slow])
@given(st.lists(st.tuples(WAITS, COMMANDS), max_size=6))
def test_a_live_session_re_flies_from_its_log(tmp_path_factory, plan):
    tmp = tmp_path_factory.mktemp("live")
    out = {k: tmp / f"live.{k}" for k in ("json", "parquet", "toml")}
    with serving("--speed", "300", "--json", str(out["json"]), "--telemetry",
                 str(out["parquet"]), "--save-commands", str(out["toml"])) as s:
        asyncio.run(_fly(s, plan))
        code, _, err = s.finish()
    assert code == 0, err
    again = {k: tmp / f"again.{k}" for k in ("json", "parquet")}
    r = subprocess.run([*ALLSKY, "run", "--commands", str(out["toml"]), "--json",
                        str(again["json"]), "--telemetry", str(again["parquet"]), "--quiet"],
                       capture_output=True, text=True, timeout=TIMEOUT_S, check=False)
    assert r.returncode in (0, 1), r.stderr
    assert json.loads(again["json"].read_text()) == json.loads(out["json"].read_text())
    from allsky.apps.telemetry_files import read

    a, b = read(out["parquet"])[0], read(again["parquet"])[0]
    assert a.shape == b.shape and np.array_equal(a.view(np.uint64), b.view(np.uint64))
