"""A campaign that flew no run (every drawn scenario rejected) is not a success."""

from allsky.apps import campaign, cli


def test_a_campaign_whose_every_run_is_rejected_exits_2(tmp_path, capsys):
    spec = tmp_path / "d.toml"
    # A thrust drawn from [-2, -1] N: every drawn scenario is refused by jets.thrust_n's rule.
    spec.write_text('[dispersions]\njets.thrust_n = { dist = "uniform", low = -2.0, '
                    "high = -1.0 }\n")
    code = cli.main(["montecarlo", "--runs", "3", "--workers", "1", "--quiet", "--disperse",
                     str(spec), "--json", str(tmp_path / "mc.json")])
    err = capsys.readouterr().err
    assert code == 2, err
    line = err.strip().splitlines()[-1]
    assert line.startswith("allsky: error: no run of the campaign was flown (3 invalid)"), err
    assert (tmp_path / "mc.json").exists()  # the summary says what happened


def test_a_campaign_with_a_run_flown_exits_0():
    base = {"recorded": 3, "complete": 0, "aborted": 1, "invalid": 2, "error": 0,
            "worker_died": 0, "abort_reasons": {}}
    assert campaign.no_run_flown(base) == 0
    assert campaign.no_run_flown({**base, "aborted": 0, "error": 1, "invalid": 2,
                                  "abort_reasons": {"x": 1}}) == 3
