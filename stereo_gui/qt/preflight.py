"""Checks before Qt starts, so that a machine without a display or without Qt's system libraries
gets one line that says what to do instead of Qt's abort (exit 134) and its misleading hint to
install libxcb-cursor0.

Imports no Qt: it runs before PySide6 is imported. Only Linux (and other X11/Wayland systems)
is checked; Windows and macOS always have their platform plugin's libraries.
"""

from __future__ import annotations

import ctypes
import importlib.util
import logging
import os
import re
import shutil
import subprocess
import sys
from collections.abc import Callable, Mapping, MutableMapping
from pathlib import Path

from stereo_gui.core.errors import StereoGuiError

log = logging.getLogger(__name__)

# loads a shared library by path or name (ctypes.CDLL; the tests give fakes)
Loader = Callable[[str], ctypes.CDLL]

NO_DISPLAY = ("no display found (DISPLAY and WAYLAND_DISPLAY are not set): start stereo-gui from "
              "a desktop session, under a virtual X server (xvfb-run -a stereo-gui), or without "
              "a window (QT_QPA_PLATFORM=offscreen stereo-gui)")

# the shared libraries Qt's wheels need from the system, and the Debian/Ubuntu packages that
# provide them
DEBIAN_PACKAGES: dict[str, str] = {
    "libGL.so.1": "libgl1",
    "libEGL.so.1": "libegl1",
    "libOpenGL.so.0": "libopengl0",
    "libGLX.so.0": "libglx0",
    "libxkbcommon.so.0": "libxkbcommon0",
    "libxkbcommon-x11.so.0": "libxkbcommon-x11-0",
    "libfontconfig.so.1": "libfontconfig1",
    "libfreetype.so.6": "libfreetype6",
    "libdbus-1.so.3": "libdbus-1-3",
    "libglib-2.0.so.0": "libglib2.0-0",
    "libgthread-2.0.so.0": "libglib2.0-0",
    "libX11.so.6": "libx11-6",
    "libX11-xcb.so.1": "libx11-xcb1",
    "libxcb.so.1": "libxcb1",
    "libxcb-cursor.so.0": "libxcb-cursor0",
    "libxcb-icccm.so.4": "libxcb-icccm4",
    "libxcb-image.so.0": "libxcb-image0",
    "libxcb-keysyms.so.1": "libxcb-keysyms1",
    "libxcb-randr.so.0": "libxcb-randr0",
    "libxcb-render-util.so.0": "libxcb-render-util0",
    "libxcb-render.so.0": "libxcb-render0",
    "libxcb-shape.so.0": "libxcb-shape0",
    "libxcb-shm.so.0": "libxcb-shm0",
    "libxcb-sync.so.1": "libxcb-sync1",
    "libxcb-util.so.1": "libxcb-util1",
    "libxcb-xfixes.so.0": "libxcb-xfixes0",
    "libxcb-xinerama.so.0": "libxcb-xinerama0",
    "libxcb-xinput.so.0": "libxcb-xinput0",
    "libxcb-xkb.so.1": "libxcb-xkb1",
    "libSM.so.6": "libsm6",
    "libICE.so.6": "libice6",
    "libwayland-client.so.0": "libwayland-client0",
    "libwayland-cursor.so.0": "libwayland-cursor0",
    "libwayland-egl.so.1": "libwayland-egl1",
}

_MISSING = re.compile(r"([\w.+-]+\.so[.\d]*): cannot open shared object file")


class PreflightError(StereoGuiError):
    """Qt cannot start here; the message is the one line to show (exit status 2)."""


def platform_name(env: Mapping[str, str]) -> str:
    """The Qt platform plugin Qt will load: QT_QPA_PLATFORM's first, else xcb or wayland."""
    chosen = env.get("QT_QPA_PLATFORM", "").strip()
    if chosen:
        return chosen.split(";")[0].split(":")[0].strip().lower()
    if env.get("WAYLAND_DISPLAY") and (not env.get("DISPLAY")
                                       or env.get("XDG_SESSION_TYPE", "").lower() == "wayland"):
        return "wayland"
    return "xcb"


def _qt_dir() -> Path | None:
    spec = importlib.util.find_spec("PySide6")
    if spec is None or not spec.submodule_search_locations:
        return None
    return Path(list(spec.submodule_search_locations)[0])


def _missing_with_ldd(path: Path) -> list[str]:
    """Every library `path` needs that the dynamic loader cannot find (ldd's "not found")."""
    ldd = shutil.which("ldd")
    if not ldd:
        return []
    try:
        out = subprocess.run([ldd, str(path)], capture_output=True, text=True, timeout=20).stdout
    except (OSError, subprocess.SubprocessError):
        return []
    return sorted({line.split("=>")[0].strip() for line in out.splitlines()
                   if "not found" in line})


def missing_libraries(load: Loader = ctypes.CDLL, env: Mapping[str, str] | None = None
                      ) -> list[str]:
    """The system libraries missing for Qt's GUI modules and the platform plugin Qt will use
    ([] when all load). `load(path)` loads a shared library (ctypes.CDLL; tests replace it)."""
    env = os.environ if env is None else env
    root = _qt_dir()
    if root is None:
        return []
    qt = root / "Qt"
    name = platform_name(env)
    candidates = sorted((root.glob("QtWidgets.*")))[:1] + [qt / "plugins" / "platforms" /
                                                           f"libq{name}.so"]
    for path in candidates:
        if not path.is_file():
            continue
        try:
            load(str(path))
        except OSError as exc:
            first = _MISSING.search(str(exc))
            found = _missing_with_ldd(path) if load is ctypes.CDLL else []
            libs = found or ([first.group(1)] if first else [])
            if libs:
                return libs
            log.debug("loading %s failed: %s", path, exc)
    return []


def _can_connect_x(display: str, load: Loader = ctypes.CDLL) -> bool | None:
    """Whether an X server answers at `display` (None when libxcb cannot be loaded to ask)."""
    try:
        xcb = load("libxcb.so.1")
    except OSError:
        return None
    xcb.xcb_connect.restype = ctypes.c_void_p
    xcb.xcb_connect.argtypes = [ctypes.c_char_p, ctypes.c_void_p]
    xcb.xcb_connection_has_error.argtypes = [ctypes.c_void_p]
    xcb.xcb_disconnect.argtypes = [ctypes.c_void_p]
    conn = xcb.xcb_connect(display.encode(), None)
    try:
        return bool(xcb.xcb_connection_has_error(conn) == 0)
    finally:
        xcb.xcb_disconnect(conn)


def libraries_message(libs: list[str]) -> str:
    """One line naming the missing libraries and the Debian/Ubuntu packages that provide them."""
    packages = list(dict.fromkeys(DEBIAN_PACKAGES[lib] for lib in libs if lib in DEBIAN_PACKAGES))
    unknown = [lib for lib in libs if lib not in DEBIAN_PACKAGES]
    text = (f"Qt cannot start: the system {'library' if len(libs) == 1 else 'libraries'} "
            f"{', '.join(libs)} {'is' if len(libs) == 1 else 'are'} missing")
    if packages:
        text += f"; on Debian/Ubuntu: sudo apt install {' '.join(packages)}"
    if unknown:
        text += (f"; find the package that provides {', '.join(unknown)} with your system's "
                 "package search (apt-file search)")
    return text


def offscreen_without_display(env: MutableMapping[str, str] | None = None) -> bool:
    """For a window nobody needs to see (`bench --window`): Qt's offscreen platform when neither
    DISPLAY nor WAYLAND_DISPLAY is set and no platform was chosen; True when it was set."""
    env = os.environ if env is None else env
    if env.get("QT_QPA_PLATFORM", "").strip() or env.get("DISPLAY") or env.get("WAYLAND_DISPLAY"):
        return False
    env["QT_QPA_PLATFORM"] = "offscreen"
    return True


def check_gui_can_start(env: Mapping[str, str] | None = None, platform: str | None = None,
                        load: Loader = ctypes.CDLL) -> None:
    """Raise PreflightError with one line when Qt's window cannot start here: no display, a
    display that does not answer, or a missing system library."""
    env = os.environ if env is None else env
    platform = sys.platform if platform is None else platform
    if not platform.startswith(("linux", "freebsd", "openbsd", "netbsd")):
        return
    chosen = env.get("QT_QPA_PLATFORM", "").strip()
    if not chosen and not env.get("DISPLAY") and not env.get("WAYLAND_DISPLAY"):
        raise PreflightError(NO_DISPLAY)
    try:
        libs = missing_libraries(load, env)
    except Exception:  # noqa: BLE001 - the check must never be the reason the GUI cannot start
        log.debug("checking Qt's libraries failed", exc_info=True)
        libs = []
    if libs:
        raise PreflightError(libraries_message(libs))
    if platform_name(env) == "xcb" and env.get("DISPLAY"):
        try:
            answers = _can_connect_x(env["DISPLAY"], load)
        except Exception:  # noqa: BLE001
            answers = None
        if answers is False:
            raise PreflightError(
                f"cannot connect to the X display {env['DISPLAY']!r} (DISPLAY): is the X server "
                "running and may this user use it? Else run under a virtual X server "
                "(xvfb-run -a stereo-gui) or without a window (QT_QPA_PLATFORM=offscreen)")
