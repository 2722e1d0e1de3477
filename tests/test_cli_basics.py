"""The command line's shared behaviour: version, usage errors, exit status 2 without a traceback."""

import subprocess
import sys

import pytest

from stereo_gui import __version__
from stereo_gui.cli import SUBCOMMANDS, main


def test_version(capsys):
    with pytest.raises(SystemExit) as exc:
        main(["--version"])
    assert exc.value.code == 0
    assert __version__ in capsys.readouterr().out


def test_help_lists_every_subcommand_with_what_it_does(capsys):
    with pytest.raises(SystemExit) as exc:
        main(["--help"])
    assert exc.value.code == 0
    out = capsys.readouterr().out
    for name, (_module, text) in SUBCOMMANDS.items():
        assert f"  {name}" in out and text in out


def test_unknown_option_exits_2_with_one_line():
    proc = subprocess.run([sys.executable, "-m", "stereo_gui", "--no-such-option"],
                          capture_output=True, text=True)
    assert proc.returncode == 2
    assert "Traceback" not in proc.stderr
    assert proc.stderr.strip().splitlines()[-1].startswith("stereo-gui: error:")
