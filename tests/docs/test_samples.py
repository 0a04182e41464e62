"""The sample outputs of the documentation are what the commands print today.

Each plain code block (no language) of a page in :data:`SAMPLES` is a
sample: its lines must appear in the command's output, in order; a line
``...`` stands for any number of lines left out, a line ending in ``  ...``
for a line that goes on, and a first line ``$ allsky ...`` shows the command
(it must be the one run, and is not output). Each command runs in an empty
folder, where the files it writes go.
"""

import contextlib
import io
import shlex
from pathlib import Path

import pytest

from allsky.apps import cli

DOCS = Path(__file__).resolve().parents[2] / "docs"
#: Page -> the command of each of its samples, in the page's order.
SAMPLES = {
    "getting_started.md": (["run", "--quiet"], ["step", "--no-pause", "--quiet"]),
    # the drift DAC at full scale: the report's first lines
    "journal.md": (["run", "--quiet", "--set", "gyro.drift_deg_h=[4.0,0.0,0.0]",
                    "--set", "electronics.integrator_drift_deg_h=[2.0,0.0,0.0]",
                    "--set", "target.hold_s=300"],),
    # the wheels' envelopes, and the figure written
    "envelopes.md": (["analyze", "--envelope", "--plot", "docs/img/envelope.png"],),
}
CASES = [(page, i) for page, commands in SAMPLES.items() for i in range(len(commands))]


def samples(page: str = "getting_started.md", commands: bool = False) -> list:
    """The page's plain code blocks, as lists of lines.

    A first line ``$ COMMAND`` is left out; with ``commands``, the blocks'
    commands are given instead (None for a block without one).
    """
    blocks, block, language = [], None, None
    for line in (DOCS / page).read_text().splitlines():
        if line.startswith("```"):
            if block is None:
                block, language = [], line[3:].strip()
            else:
                if not language:
                    shown = block[0][2:] if block and block[0].startswith("$ ") else None
                    blocks.append(shown if commands else block[1:] if shown else block)
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


@pytest.mark.parametrize("page", SAMPLES)
def test_the_page_has_a_sample_for_each_command(page):
    assert len(samples(page)) == len(SAMPLES[page])


@pytest.mark.parametrize("page, index", CASES, ids=[f"{p[:-3]}-{i + 1}" for p, i in CASES])
def test_each_sample_is_what_the_command_prints(page, index, tmp_path, monkeypatch):
    sample, argv = samples(page)[index], SAMPLES[page][index]
    shown = samples(page, commands=True)[index]
    assert shown in (None, shlex.join(["allsky", *argv])), f"docs/{page} shows {shown!r}"
    monkeypatch.chdir(tmp_path)
    for arg in argv:  # the folders of the files it writes (docs/img/envelope.png)
        if "/" in arg and "=" not in arg:
            (tmp_path / arg).parent.mkdir(parents=True, exist_ok=True)
    assert unmatched(sample, _output(argv)) == [], (
        f"docs/{page} sample {index + 1} differs from allsky {' '.join(argv)}")


def test_a_changed_line_is_found():
    assert unmatched(["a", "...", "c"], "a\nb\nc\n") == []
    assert unmatched(["a", "c"], "a\nb\nc\n") == ["c"]  # no gap without "..."
    assert unmatched(["a", "x  ..."], "a\nx y z\n") == []
    assert unmatched(["a", "z"], "a\nb\n") == ["z"]


#: docs/montecarlo.md's example campaign: 500 runs, about 30 s on two cores.
CAMPAIGN = ["montecarlo", "--disperse", str(DOCS / "examples" / "gyro_and_sky_dispersions.toml"),
            "--runs", "500", "--out", "mc/"]


@pytest.mark.slow
def test_the_campaign_sample_is_what_the_campaign_prints(tmp_path, monkeypatch):
    """The page's first output block is the example campaign's table, line for line."""
    monkeypatch.chdir(tmp_path)
    sample = samples("montecarlo.md")[0]
    assert sample[0].startswith("Monte Carlo campaign: 500 of 500 runs recorded")
    assert unmatched(sample, _output(CAMPAIGN)) == [], "docs/montecarlo.md's campaign differs"
