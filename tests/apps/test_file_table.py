"""One table of every command's files: the clash check derived from it for every command."""

import argparse
import os

import pytest

from allsky.apps import cli

#: Metavars that name a file or a directory (options taking a number or a name do not).
FILE_METAVARS = {"PATH", "FILE", "DIR", "PNG", "SPEC", "STATE", "JSON", "SUMMARY.json",
                 "TELEMETRY", "SCENARIO"}


def _leaves():
    sub = next(a for a in cli._parser()._actions if isinstance(a, argparse._SubParsersAction))
    for name, sp in sub.choices.items():
        if name == "config":
            inner = next(a for a in sp._actions if isinstance(a, argparse._SubParsersAction))
            for sp2 in inner.choices.values():
                yield name, sp2
        else:
            yield name, sp


def test_every_file_option_of_every_command_is_in_the_table():
    for name, sp in _leaves():
        assert name in cli.FILES, name
        listed = {d for d, *_ in cli.FILES[name]}
        for action in sp._actions:
            if action.metavar in FILE_METAVARS:
                assert action.dest in listed, (name, action.dest)
        for dest, option, role, kind in cli.FILES[name]:
            assert role in ("in", "out")
            assert any(a.dest == dest for a in sp._actions), (name, dest)


@pytest.fixture(autouse=True)
def _no_flight(monkeypatch):
    """A command the check lets through returns 99 at once rather than fly (or serve)."""
    monkeypatch.setattr(cli, "_run", lambda cfg, args: 99)


def _refused(argv, capsys, what):
    code = cli.main(argv)
    err = capsys.readouterr().err
    assert code == 2, err
    assert err.startswith("allsky: error:") and what in err, err
    return err


def test_run_commands_log_cannot_be_overwritten_by_json(tmp_path, capsys):
    log = tmp_path / "log.toml"
    log.write_text('format = 1\n')
    before = log.read_bytes()
    _refused(["run", "--commands", str(log), "--json", str(log)], capsys, "--commands")
    assert log.read_bytes() == before


def test_serve_save_commands_cannot_name_the_scenario(tmp_path, capsys):
    scen = tmp_path / "s.toml"
    scen.write_text("")
    _refused(["serve", str(scen), "--no-browser", "--save-commands", str(scen)], capsys,
             "SCENARIO")
    assert scen.read_text() == ""


def test_serve_two_outputs_one_file_refused(tmp_path, capsys):
    q = tmp_path / "q.toml"
    _refused(["serve", "--no-browser", "--json", str(q), "--save-commands", str(q)], capsys,
             "writes the same file")
    assert not q.exists()


@pytest.mark.parametrize("how", ["symlink", "hardlink"])
def test_links_to_an_input_are_the_input(tmp_path, capsys, how):
    scen = tmp_path / "s.toml"
    scen.write_text("")
    other = tmp_path / "other.json"
    (os.symlink if how == "symlink" else os.link)(scen, other)
    _refused(["run", str(scen), "--json", str(other)], capsys, "SCENARIO")
    _refused(["serve", str(scen), "--no-browser", "--html", str(tmp_path / "x.html"),
              "--json", str(other)], capsys, "SCENARIO")
    assert scen.read_text() == ""


def test_step_from_state_and_disperse_are_inputs(tmp_path, capsys):
    spec = tmp_path / "d.toml"
    spec.write_text("[dispersions]\n")
    _refused(["montecarlo", "--runs", "1", "--disperse", str(spec), "--json", str(spec)],
             capsys, "--disperse")
    _refused(["run", "--disperse", str(spec), "--telemetry", str(spec)], capsys, "--disperse")


def test_control_characters_in_a_path_are_escaped_in_the_message(tmp_path, capsys):
    path = tmp_path / "missing\x1b[2J\x07.toml"
    err = _refused(["config", "check", str(path)], capsys, "not found")
    assert "\x1b" not in err and "\x07" not in err and "\\x1b[2J\\x07" in err


def test_a_nul_in_an_output_path_is_a_usage_error(tmp_path, capsys):
    _refused(["run", "--json", str(tmp_path / "a\x00b.json")], capsys, "a NUL character")


def test_the_interrupted_line_names_what_was_written(tmp_path):
    from allsky.apps import output

    output.forget_written()
    assert cli._interrupted_line().endswith("; nothing written")
    output.write_atomic(tmp_path / "a.json", "{}")
    line = cli._interrupted_line()
    assert line.startswith("allsky: interrupted; nothing half-written")
    assert line.endswith(f"written whole: {tmp_path / 'a.json'}")
    output.forget_written()


def test_a_nul_in_an_input_path_is_a_usage_error(tmp_path, capsys, monkeypatch):
    monkeypatch.undo()  # the reader itself refuses it (no flight: plot reads first)
    err = _refused(["plot", str(tmp_path / "\x07\x00.csv")], capsys, "telemetry file")
    assert "\x00" not in err and "\x07" not in err
