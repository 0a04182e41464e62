"""Ground commands as plan changes (allsky.sequencer.ground): the module's table, case by case."""

import pytest

from allsky.config import load_scenario
from allsky.sequencer import ground
from allsky.sequencer.ground import Replan, Where
from allsky.sim.mission import Mission

PLAN = ("1", "2", "3", "4", "5", "6-1", "6-2")


@pytest.fixture(scope="module")
def cfg():
    return load_scenario()


@pytest.fixture(scope="module")
def three():
    return load_scenario("docs/examples/three_targets.toml")


def at(plan, mode, flying=True, status="running", k=None):
    return Where(tuple(plan), plan.index(mode) if k is None else k, flying, status)


@pytest.mark.parametrize("mode, phase", [("1", "before"), ("4", "before"), ("6-1", "turning"),
                                          ("6-2", "turning")])
def test_phases(mode, phase):
    assert ground.phase(at(PLAN, mode)) == phase


def test_a_complete_mission_is_on_target():
    assert ground.phase(Where(PLAN, 6, False, "complete")) == "on target"
    assert ground.phase(Where(PLAN, None, False, "running")) == "start"


def test_a_target_before_mode_6_replaces_the_target(cfg):
    assert ground.replan("target", at(PLAN, "3"), cfg) == Replan(PLAN, False, "replace")


def test_a_target_while_turning_follows_this_one(cfg):
    r = ground.replan("target", at(PLAN, "6-1"), cfg)
    assert r == Replan(PLAN + ("reacquire", "1", "2", "6-1", "6-2"), False, "next")


def test_a_target_on_target_ends_the_hold_and_flies_by_the_scenario_s_move(three):
    plan = tuple(Mission(three, telemetry=False).plan)
    i = plan.index("hold")
    r = ground.replan("target", Where(plan, i, True, "running"), three)
    move = ("reacquire", "1", "2", "6-1", "6-2", "hold")
    assert r.plan == plan[: i + 1] + move + plan[i + 1:] and r.end_mode and r.target == "next"


def test_hold_waits_for_the_target_then_holds_until_commanded(cfg):
    assert ground.replan("hold", at(PLAN, "4"), cfg) == Replan(PLAN + ("standby",), False, None)
    done = Where(PLAN, 6, False, "complete")
    assert ground.replan("hold", done, cfg) == Replan(PLAN + ("standby",), False, None)
    holding = Where(PLAN + ("standby",), 7, True, "running")
    with pytest.raises(ground.Refused, match="already holding"):
        ground.replan("hold", holding, cfg)
    assert ground.replan("proceed", holding, cfg) == Replan(PLAN + ("standby",), True, None)


def test_proceed_before_the_target_drops_the_planned_hold(cfg):
    plan = PLAN + ("standby",)
    assert ground.replan("proceed", at(plan, "5"), cfg) == Replan(PLAN, False, None)


def test_reacquire_before_mode_6_flies_the_references_then_the_mode_again(cfg):
    r = ground.replan("reacquire", at(PLAN, "4"), cfg)
    assert r == Replan(PLAN[:4] + ("references", "1", "2", "4", "5", "6-1", "6-2"), True, None)
    r = ground.replan("reacquire", at(PLAN, "2"), cfg)
    assert r.plan == PLAN[:2] + ("references", "1", "2", "3", "4", "5", "6-1", "6-2")


def test_recycle_before_mode_6_flies_every_mode_again(cfg):
    r = ground.replan("recycle", at(PLAN, "5"), cfg)
    assert r == Replan(PLAN[:5] + ("restart",) + PLAN, True, None)


def test_reacquire_from_mode_6_flies_the_target_again(cfg):
    r = ground.replan("reacquire", at(PLAN, "6-2"), cfg)
    assert r == Replan(PLAN + ("reacquire", "1", "2", "6-1", "6-2"), True, "again")
    r = ground.replan("recycle", Where(PLAN, 6, False, "complete"), cfg)
    assert r == Replan(PLAN + ("recycle",) + PLAN[:5] + ("6-1", "6-2"), False, "again")


def test_an_aborted_mission_takes_only_reacquire_or_recycle(cfg):
    aborted = Where(PLAN, 3, False, "aborted")
    for command in ("target", "hold", "proceed"):
        with pytest.raises(ground.Refused, match="aborted in Mode 4"):
            ground.replan(command, aborted, cfg)
    r = ground.replan("reacquire", aborted, cfg)
    assert r == Replan(PLAN[:4] + ("references", "1", "2") + PLAN[3:], False, None)


def test_nothing_before_the_first_mode_but_a_target_or_a_hold(cfg):
    start = Where(PLAN, None, False, "running")
    assert ground.replan("target", start, cfg).target == "replace"
    for command in ("reacquire", "recycle", "proceed"):
        with pytest.raises(ground.Refused, match="not begun"):
            ground.replan(command, start, cfg)
