"""The command line with its standard streams full, closed, or read by a program that stops
early: a clear status or a quiet exit, never a traceback."""

from __future__ import annotations

import os
import subprocess
import sys

import pytest

CMD = [sys.executable, "-m", "stereo_gui"]


@pytest.mark.skipif(not os.path.exists("/dev/full"), reason="needs /dev/full")
def test_a_command_writing_to_a_full_device_says_so(tmp_path):
    """(argparse's own --help swallows a write error by design: a command's output is ours.)"""
    with open("/dev/full", "w") as full:
        run = subprocess.run(CMD + ["target", "-o", str(tmp_path / "t.svg")], stdout=full,
                             stderr=subprocess.PIPE, text=True, timeout=120)
    assert run.returncode == 2 and "No space left" in run.stderr and "Traceback" not in run.stderr


def test_a_reader_that_stops_early_ends_it_quietly():
    proc = subprocess.Popen(CMD + ["bench", "--help"], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE)
    proc.stdout.close()  # the reader is gone before the help is written
    err = proc.stderr.read().decode()
    proc.wait(120)
    assert "Traceback" not in err and "BrokenPipe" not in err
    assert proc.returncode == 0


def test_a_closed_stderr_does_not_crash_a_refusal():
    run = subprocess.run(["sh", "-c", " ".join(CMD) + " measure --calib /nonexistent a b "
                          "--at 1,1 2>&-; echo status $?"], capture_output=True, text=True,
                         timeout=120)
    assert run.stdout.strip().endswith("status 2"), run.stdout + run.stderr


def test_sigterm_leaves_no_temporary_files(tmp_path):
    """`simulate` stopped by SIGTERM mid-way: what it wrote is whole, nothing hidden is left."""
    from tests.cli_output import stop_with_signal

    out = tmp_path / "set"
    code, _out, err = stop_with_signal(CMD + ["simulate", str(out), "--pairs", "400"],
                                       lambda _p: out.is_dir() and any(out.glob("*.png")))
    assert code == 130 and "interrupted" in err and "Traceback" not in err
    assert [p.name for p in out.iterdir() if p.name.startswith(".")] == []
