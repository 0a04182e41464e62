"""A FIFO with no other end: reported in one line after a second, then waited for."""

import os
import subprocess
import sys
import threading
import time
from pathlib import Path

from allsky.config import toml_io

SRC = Path(__file__).resolve().parents[2] / "src"


def test_an_input_fifo_without_writer_is_reported_then_read(tmp_path, capsys):
    fifo = tmp_path / "s.toml"
    os.mkfifo(fifo)

    def late_writer():
        time.sleep(toml_io.FIFO_PARTNER_S * 2)
        with open(fifo, "wb") as f:
            f.write(b"[mission]\nseed = 3\n")

    threading.Thread(target=late_writer, daemon=True).start()
    data = toml_io.read_bounded(fifo, 1000, "scenario file")
    assert data == b"[mission]\nseed = 3\n"
    err = capsys.readouterr().err
    assert err.startswith(f"allsky: scenario file {fifo} is a FIFO with no writer yet; "
                          "waiting for one")
    assert len(err.splitlines()) == 1


def test_an_output_fifo_without_reader_is_reported_and_ctrl_c_ends_the_wait(tmp_path):
    fifo = tmp_path / "out.json"
    os.mkfifo(fifo)
    env = {**os.environ, "PYTHONPATH": str(SRC)}
    proc = subprocess.Popen([sys.executable, "-m", "allsky", "scenarios", "--json", str(fifo)],
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
                            env=env)
    line = proc.stderr.readline()  # comes after the second, whatever the load (no timing)
    assert line.startswith(f"allsky: output {fifo} is a FIFO with no reader yet"), line
    proc.send_signal(2)
    _, rest = proc.communicate(timeout=60)
    assert proc.returncode == 130, rest
    assert rest.strip().splitlines()[-1].startswith("allsky: interrupted")
    assert "Traceback" not in rest
