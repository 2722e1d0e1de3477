"""The command line's shared behaviour: version, usage errors, exit status 2 without a traceback."""

import subprocess
import sys

from stereo_gui import __version__
from stereo_gui.cli import main


def test_version(capsys):
    try:
        main(["--version"])
    except SystemExit as exc:
        assert exc.code == 0
    assert __version__ in capsys.readouterr().out


def test_unknown_option_exits_2_with_one_line():
    proc = subprocess.run([sys.executable, "-m", "stereo_gui", "--no-such-option"],
                          capture_output=True, text=True)
    assert proc.returncode == 2
    assert "Traceback" not in proc.stderr
    assert proc.stderr.strip().splitlines()[-1].startswith("stereo-gui: error:")
