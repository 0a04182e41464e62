"""Shared fixtures: the default mission flown once, saved at every mode boundary."""

import pytest

from allsky.apps import states
from allsky.config.scenario import load_scenario
from allsky.sequencer.master_sequencer import MODES
from allsky.sim.mission import Mission


@pytest.fixture(scope="session")
def default_cfg():
    return load_scenario()


@pytest.fixture(scope="session")
def saved_states(tmp_path_factory, default_cfg):
    """Fly the default mission once; return ``{mode: path of the state saved before it}``.

    Also returns the uninterrupted mission under the key ``"mission"``.
    """
    d = tmp_path_factory.mktemp("states")
    m = Mission(default_cfg)
    paths = {}
    for name in MODES:
        paths[name] = states.save(m, d / f"before_{name}.npz")
        m.run_mode()
    assert m.status == "complete", m.abort_reason
    paths["end"] = states.save(m, d / "end.npz")
    paths["mission"] = m
    return paths
