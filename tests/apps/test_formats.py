"""Versioned files: the summary JSON and the command log say their format, and refuse another."""

import json
import re

import pytest

from allsky.apps.cli import main
from allsky.apps.summaries import SUMMARY_FORMAT, read_summary, summary_text
from allsky.config import ConfigError
from allsky.sim import commands as C


@pytest.fixture(scope="module")
def summary(tmp_path_factory):
    path = tmp_path_factory.mktemp("s") / "s.json"
    assert main(["run", "--quiet", "--json", str(path)]) == 0
    return path


def test_the_summary_json_starts_with_its_format(summary):
    text = summary.read_text()
    data = json.loads(text)
    assert next(iter(data)) == "format" and data["format"] == SUMMARY_FORMAT == 1
    assert read_summary(summary)["status"] == "complete"
    assert summary_text({"status": "x"}).startswith('{\n  "format": 1,')


@pytest.mark.parametrize("value", [2, 0, "1", 1.0, None, True])
def test_a_summary_of_another_format_is_refused(summary, tmp_path, value):
    data = json.loads(summary.read_text())
    data["format"] = value
    path = tmp_path / "other.json"
    path.write_text(json.dumps(data))
    with pytest.raises(ConfigError, match="this allsky reads summaries of format 1"):
        read_summary(path)


def test_a_summary_written_before_the_format_key_is_read(summary, tmp_path):
    data = json.loads(summary.read_text())
    del data["format"]
    path = tmp_path / "old.json"
    path.write_text(json.dumps(data))
    assert read_summary(path)["status"] == "complete"


@pytest.mark.parametrize("head, words", [
    ("", "format: missing: a command log says its format"),
    ("format = 2\n", "this allsky reads command logs of format 1"),
    ('format = "1"\n', "this allsky reads command logs of format 1"),
])
def test_a_command_log_without_its_format_or_of_another_is_refused(tmp_path, capsys, head,
                                                                   words):
    log = tmp_path / "log.toml"
    log.write_text(head + '[[commands]]\nt_s = 3.0\nkind = "end"\n')
    with pytest.raises(ConfigError, match=words):
        C.read_log(log)
    assert main(["run", "--quiet", "--commands", str(log)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("allsky: error:") and words in err and len(err.splitlines()) == 1


@pytest.mark.parametrize("table", ["truth", "calibration"])
@pytest.mark.parametrize("word", ["drift_deg_h", "scale_factor", "cross_coupling"])
def test_a_summary_whose_words_lack_one_is_refused(summary, tmp_path, table, word):
    """Found by the bad-input campaign: replay and plot read all three words of each."""
    data = json.loads(summary.read_text())
    del data[table][word]
    path = tmp_path / "s.json"
    path.write_text(json.dumps(data))
    with pytest.raises(ConfigError, match=f"{table}.{word} is missing"):
        read_summary(path)


@pytest.mark.parametrize("field, value, words", [
    ("seed", {"a": 1}, "seed is not"), ("end", [1], "end is not"),
    ("events", [{"kind": "nope", "t_s": 0.0}], "events[0].kind 'nope' is not a journal kind"),
    ("events", [{"t_s": 0.0}], "events[0].kind is missing"), ("warnings", [1], "warnings"),
])
def test_a_summary_field_the_page_reads_is_checked(summary, tmp_path, field, value, words):
    """Found by the bad-input campaign: a seed that is a table ended replay with exit 3."""
    data = json.loads(summary.read_text())
    data[field] = value
    path = tmp_path / "s.json"
    path.write_text(json.dumps(data))
    with pytest.raises(ConfigError, match=re.escape(words)):
        read_summary(path)
