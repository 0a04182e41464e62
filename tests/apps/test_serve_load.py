"""Ten clients on one session: the mission keeps its pace, and no journal entry is lost.

A whole default mission at x200 (1313 s of mission time, 6.6 s of wall time
at that pace), watched by one WebSocket client, then by ten (one of them
commanding), alternately, twice each, on loopback. The flight's own wall
clock (``session.wall_s``: the wall time it has flown, waiting for no client
with ``--pause-when-alone``) at completion must be within 10 % of the one
client's, and every client must hold the whole journal the session wrote.
Bounded: four sessions, each ended by its client as soon as the mission is
complete, each step within TIMEOUT_S.
"""

import asyncio
import json
import statistics

from tests.apps.test_serve import Client, Session

SPEED = 200
CLIENTS = 10
#: Arms in the order flown: one client, ten, one, ten (alternating, one sitting).
ARMS = (1, CLIENTS, 1, CLIENTS)
#: The ten clients' wall time may exceed the one client's by this fraction at most.
SLOWER_AT_MOST = 0.10


async def watch(url, n):
    """``n`` clients on the session at ``url``; the first ends it once the mission is complete."""
    clients = await asyncio.gather(*(Client.connect(url) for _ in range(n)))
    first = clients[0]
    await first.until(lambda c: c.session.get("status") == "complete")
    wall_s, t_s = first.session["wall_s"], first.session["t_s"]
    answer = await first.command({"kind": "end"})
    assert answer["type"] == "done"
    await asyncio.gather(*(c.until(lambda c: False) for c in clients))
    for c in clients:
        await c.close()
    return wall_s, t_s, [c.journal for c in clients], [c.rows for c in clients]


def test_ten_clients_keep_up_with_a_whole_mission_at_x200(tmp_path):
    walls = {1: [], CLIENTS: []}
    for k, n in enumerate(ARMS):
        summary = tmp_path / f"s{k}.json"
        s = Session("--speed", str(SPEED), "--pause-when-alone", "--json", str(summary))
        try:
            wall_s, t_s, journals, rows = asyncio.run(watch(s.ws_url, n))
            code, _, err = s.finish()
        finally:
            s.kill()
        assert code == 0, err
        events = json.loads(summary.read_text())["events"]
        assert all(j == events for j in journals), "a client lost journal entries"
        assert all(r > 0 for r in rows)
        assert abs(wall_s - t_s / SPEED) < 0.5 * t_s / SPEED  # paced, not flown flat out
        walls[n].append(wall_s)
    one, ten = statistics.mean(walls[1]), statistics.mean(walls[CLIENTS])
    print(f"\nwall time of a whole mission at x{SPEED}: 1 client {walls[1]} s, "
          f"{CLIENTS} clients {walls[CLIENTS]} s; ratio {ten / one:.3f}")
    assert ten <= (1.0 + SLOWER_AT_MOST) * one, (walls, ten / one)
