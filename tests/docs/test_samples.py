"""The sample outputs of docs/getting_started.md are what the commands print today.

Each plain code block of the page (no language) is a sample: its lines must
appear in the command's output, in order; a line ``...`` stands for any
number of lines left out, and a line ending in ``  ...`` for a line that
goes on.
"""

import contextlib
import io
from pathlib import Path

import pytest

from allsky.apps import cli

PAGE = Path(__file__).resolve().parents[2] / "docs" / "getting_started.md"
#: The samples in the page's order, and the command each shows.
COMMANDS = (["run", "--quiet"], ["step", "--no-pause", "--quiet"])


def samples() -> list:
    """The page's plain code blocks, as lists of lines."""
    blocks, block, language = [], None, None
    for line in PAGE.read_text().splitlines():
        if line.startswith("```"):
            if block is None:
                block, language = [], line[3:].strip()
            else:
                if not language:
                    blocks.append(block)
                block = None
        elif block is not None:
            block.append(line)
    return blocks


def _output(argv) -> str:
    out = io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(io.StringIO()):
        assert cli.main(argv) == 0
    return out.getvalue()


def unmatched(sample, output) -> list:
    """The sample's lines not found in ``output`` in order (empty: the sample is right)."""
    lines, at, missing = output.splitlines(), 0, []
    gap = False
    for want in sample:
        if want.strip() == "...":
            gap = True
            continue
        prefix = want[:-5] if want.endswith("  ...") else None
        for i in range(at, len(lines) if gap or at == 0 else min(at + 1, len(lines))):
            if lines[i] == want or (prefix is not None and lines[i].startswith(prefix)):
                at, gap = i + 1, False
                break
        else:
            missing.append(want)
    return missing


def test_the_page_has_a_sample_for_each_command():
    assert len(samples()) == len(COMMANDS)


@pytest.mark.parametrize("index", range(len(COMMANDS)))
def test_each_sample_is_what_the_command_prints(index):
    sample = samples()[index]
    assert unmatched(sample, _output(COMMANDS[index])) == [], (
        f"docs/getting_started.md sample {index + 1} differs from allsky "
        f"{' '.join(COMMANDS[index])}")


def test_a_changed_line_is_found():
    assert unmatched(["a", "...", "c"], "a\nb\nc\n") == []
    assert unmatched(["a", "c"], "a\nb\nc\n") == ["c"]  # no gap without "..."
    assert unmatched(["a", "x  ..."], "a\nx y z\n") == []
    assert unmatched(["a", "z"], "a\nb\n") == ["z"]
