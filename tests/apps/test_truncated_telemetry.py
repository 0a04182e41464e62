"""A telemetry CSV cut short at a line boundary is named as truncated, not plotted."""

import numpy as np
import pytest

from allsky.apps import telemetry_files
from allsky.apps.cli import main
from allsky.sim.recorder import FORMAT


@pytest.fixture(scope="module")
def csv_file(tmp_path_factory, saved_states):
    path = tmp_path_factory.mktemp("t") / "t.csv"
    telemetry_files.write(path, saved_states["mission"].telemetry())
    return path


def test_the_first_line_counts_the_rows(csv_file):
    first = csv_file.read_text().split("\n", 1)[0]
    table, _ = telemetry_files.read(csv_file)
    assert first == f"# allsky telemetry format {FORMAT}; rows {len(table)}"


def test_a_file_cut_at_a_line_boundary_is_truncated(csv_file, tmp_path, capsys):
    lines = csv_file.read_text().splitlines(keepends=True)
    cut = tmp_path / "cut.csv"
    cut.write_text("".join(lines[:len(lines) // 2]))
    with pytest.raises(telemetry_files.TelemetryError, match="truncated: .* rows its first"):
        telemetry_files.read(cut)
    assert main(["plot", str(cut), "--out", str(tmp_path / "figs")]) == 2
    err = capsys.readouterr().err
    assert "truncated" in err and str(cut) in err and len(err.splitlines()) == 1


def test_a_file_without_the_count_is_read_as_before(csv_file, tmp_path):
    text = csv_file.read_text()
    first, rest = text.split("\n", 1)
    old = tmp_path / "old.csv"
    old.write_text(first.split(";")[0] + "\n" + rest)
    a, _ = telemetry_files.read(old)
    b, _ = telemetry_files.read(csv_file)
    assert np.array_equal(a, b, equal_nan=True)
