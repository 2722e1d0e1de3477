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


@pytest.mark.parametrize("argv", [["--no-such-option"], *[[name, "--no-such-option"]
                                                          for name in SUBCOMMANDS]])
def test_every_subcommand_has_one_error_prefix(argv, capsys):
    """Usage errors of every subcommand, like bad input, start "stereo-gui: error:"."""
    with pytest.raises(SystemExit) as exc:
        main(argv)
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("stereo-gui: error: ")
    if argv[0] in SUBCOMMANDS:
        assert err.startswith(f"stereo-gui: error: {argv[0]}: ")
        assert f"stereo-gui {argv[0]} --help" in err


def test_bad_input_and_warnings_share_the_prefix(tmp_path, capsys):
    assert main(["measure", "--calib", str(tmp_path / "none.yaml"), "a.png", "b.png",
                 "--at", "1,1"]) == 2
    assert capsys.readouterr().err.startswith("stereo-gui: error: ")
    code = ("import logging; from stereo_gui.cli import setup_logging; setup_logging(False); "
            "logging.getLogger('stereo_gui.sources.open').warning('no cameras were found'); "
            "logging.getLogger('stereo_gui.x').info('not shown')")
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert proc.stderr == "stereo-gui: warning: no cameras were found\n"
