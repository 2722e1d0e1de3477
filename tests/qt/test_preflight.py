"""Before Qt starts: no display, a display that does not answer, or a missing Qt system library
is one line and exit 2, not Qt's abort (exit 134) with its hint to install libxcb-cursor0."""

from __future__ import annotations

import os
import subprocess
import sys
import types

import pytest

from stereo_gui.qt import preflight
from stereo_gui.qt.preflight import PreflightError, check_gui_can_start


def test_without_a_display_the_gui_says_so_in_one_line_and_exits_2(tmp_path):
    env = {k: v for k, v in os.environ.items()
           if k not in ("DISPLAY", "WAYLAND_DISPLAY", "QT_QPA_PLATFORM")}
    env["STEREO_GUI_CONFIG_DIR"] = str(tmp_path / "cfg")
    proc = subprocess.run([sys.executable, "-m", "stereo_gui", "--source", "sim"], env=env,
                          capture_output=True, text=True, timeout=60)
    assert proc.returncode == 2, proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1, proc.stderr
    assert lines[0].startswith("stereo-gui: error: no display found")
    assert "xvfb-run" in lines[0] and "QT_QPA_PLATFORM=offscreen" in lines[0]
    assert "xcb-cursor" not in proc.stderr
    # subcommands and --help need no display
    proc = subprocess.run([sys.executable, "-m", "stereo_gui", "--help"], env=env,
                          capture_output=True, text=True, timeout=60)
    assert proc.returncode == 0


def _loader(missing: dict[str, str], x_answers: bool = True):
    """A stand-in for ctypes.CDLL: paths whose name contains a key fail with the dynamic
    loader's message for the value; libxcb answers `x_answers`."""
    def load(path):
        for part, lib in missing.items():
            if part in path:
                raise OSError(f"{lib}: cannot open shared object file: No such file or directory")
        if "libxcb.so" in path:  # functions take restype/argtypes like ctypes' do
            return types.SimpleNamespace(
                xcb_connect=lambda display, screen: 1,
                xcb_connection_has_error=lambda conn: 0 if x_answers else 1,
                xcb_disconnect=lambda conn: None)
        return object()

    return load


@pytest.mark.parametrize("part,lib,package", [
    ("QtWidgets", "libEGL.so.1", "libegl1"),
    ("QtWidgets", "libGL.so.1", "libgl1"),
    ("QtWidgets", "libfontconfig.so.1", "libfontconfig1"),
    ("QtWidgets", "libdbus-1.so.3", "libdbus-1-3"),
    ("libqxcb", "libxkbcommon-x11.so.0", "libxkbcommon-x11-0"),
    ("libqxcb", "libxcb-icccm.so.4", "libxcb-icccm4"),
])
def test_a_missing_system_library_is_named_with_its_package(part, lib, package):
    with pytest.raises(PreflightError) as exc:
        check_gui_can_start({"DISPLAY": ":0"}, "linux", _loader({part: lib}))
    text = str(exc.value)
    assert lib in text and f"sudo apt install {package}" in text and "\n" not in text


def test_offscreen_needs_no_display_but_its_libraries():
    check_gui_can_start({"QT_QPA_PLATFORM": "offscreen"}, "linux", _loader({}))
    with pytest.raises(PreflightError, match="libfontconfig.so.1"):
        check_gui_can_start({"QT_QPA_PLATFORM": "offscreen"}, "linux",
                            _loader({"libqoffscreen": "libfontconfig.so.1"}))


def test_a_display_that_does_not_answer_is_named():
    with pytest.raises(PreflightError, match=r"cannot connect to the X display ':77'.*xvfb-run"):
        check_gui_can_start({"DISPLAY": ":77"}, "linux", _loader({}, x_answers=False))
    check_gui_can_start({"DISPLAY": ":0"}, "linux", _loader({}, x_answers=True))


def test_other_systems_and_unknown_libraries():
    check_gui_can_start({}, "win32", _loader({"QtWidgets": "libGL.so.1"}))  # not checked there
    check_gui_can_start({}, "darwin", _loader({}))
    text = preflight.libraries_message(["libfoo.so.3", "libEGL.so.1"])
    assert "libfoo.so.3" in text and "libegl1" in text and "apt-file search" in text


def test_the_platform_qt_will_load():
    assert preflight.platform_name({"QT_QPA_PLATFORM": "vnc:size=800x600"}) == "vnc"
    assert preflight.platform_name({"QT_QPA_PLATFORM": "wayland;xcb"}) == "wayland"
    assert preflight.platform_name({"DISPLAY": ":0"}) == "xcb"
    assert preflight.platform_name({"WAYLAND_DISPLAY": "wayland-0"}) == "wayland"
    assert preflight.platform_name({"WAYLAND_DISPLAY": "w", "DISPLAY": ":0",
                                    "XDG_SESSION_TYPE": "wayland"}) == "wayland"
