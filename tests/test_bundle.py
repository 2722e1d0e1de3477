"""Packaging: the wheel carries resources/, and the PyInstaller bundle (packaging/) builds, carries
its files, leaves out what it should, and starts.

The bundle tests are slow (a build takes a minute or more), so they run only with
STEREO_GUI_BUNDLE_TESTS=1, in the test environment (`pip install -e '.[test]'`):

    STEREO_GUI_BUNDLE_TESTS=1 .venv/bin/python -m pytest tests/test_bundle.py -q -p no:cacheprovider

They use dist/stereo-gui/ when present and build it with packaging/build.sh otherwise
(STEREO_GUI_BUNDLE_REBUILD=1 forces a fresh build). Checks that need the window (the 3D view) are
run by the bundled executable itself: STEREO_GUI_BUNDLE_SMOKE=NAME (packaging/smoke.py).
"""

from __future__ import annotations

import importlib.util
import json
import os
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

from stereo_gui import __version__

REPO = Path(__file__).resolve().parents[1]
BUNDLE_DIR = REPO / "dist" / "stereo-gui"
EXE = BUNDLE_DIR / ("stereo-gui.exe" if sys.platform == "win32" else "stereo-gui")

BUILD_VENV = Path(os.environ.get("STEREO_GUI_BUILD_VENV", REPO / "build" / "package-venv"))
RESOURCES = REPO / "resources"
_ON_LINUX = sys.platform.startswith("linux")


def bundle_test(func):
    """Mark a test that needs the bundle: slow, so it runs only with STEREO_GUI_BUNDLE_TESTS=1."""
    func = pytest.mark.skipif(os.environ.get("STEREO_GUI_BUNDLE_TESTS") != "1",
                              reason="bundle tests run only with STEREO_GUI_BUNDLE_TESTS=1")(func)
    return pytest.mark.bundle(func)


def _resource_files() -> set[Path]:
    return {p.relative_to(RESOURCES) for p in RESOURCES.rglob("*")
            if p.is_file() and "__pycache__" not in p.parts}


def _slim():
    """packaging/slim.py (the bundle's ELF reader), imported from its path."""
    name = "_packaging_slim"
    if name not in sys.modules:
        spec = importlib.util.spec_from_file_location(name, REPO / "packaging" / "slim.py")
        module = importlib.util.module_from_spec(spec)
        sys.modules[name] = module  # dataclasses look their module up there
        spec.loader.exec_module(module)
    return sys.modules[name]


def _bundled_elf_files() -> dict[Path, object]:
    read_elf = _slim().read_elf
    found = {}
    for path in (BUNDLE_DIR / "_internal").rglob("*"):
        if path.is_file() and not path.is_symlink():
            info = read_elf(path)
            if info is not None:
                found[path] = info
    return found


def test_installed_package_finds_every_resource_file():
    # the editable install of the test environment (as in CI), or an installed wheel
    from stereo_gui.resources import resource_path

    for rel in sorted(_resource_files()):
        installed = resource_path(*rel.parts)
        assert installed.is_file(), f"{rel} not found at {installed}"
        assert installed.read_bytes() == (RESOURCES / rel).read_bytes()


@pytest.mark.slow
def test_wheel_builds_without_warnings_and_carries_every_resource_file(tmp_path):
    # Built from a copy, so the build leaves nothing in the checkout. pip's build isolation
    # installs the setuptools that pyproject.toml asks for (from the package index).
    src = tmp_path / "src"
    ignore = shutil.ignore_patterns("__pycache__", "*.pyc")
    for name in ("stereo_gui", "resources", "docs"):
        shutil.copytree(REPO / name, src / name, ignore=ignore)
    for name in ("pyproject.toml", "README.md"):
        shutil.copy2(REPO / name, src / name)
    proc = subprocess.run([sys.executable, "-m", "pip", "wheel", "-v", "--no-deps",
                           "-w", str(tmp_path / "wheel"), str(src)],
                          capture_output=True, text=True, timeout=600)
    output = proc.stdout + proc.stderr
    assert proc.returncode == 0, output[-3000:]
    # setuptools' warnings look like "...build_py.py:215: _Warning: Package 'x' is absent ..."
    warnings = [line for line in output.splitlines() if "Warning:" in line]
    assert not warnings, "\n".join(warnings)
    (wheel,) = (tmp_path / "wheel").glob("stereo_gui-*.whl")
    with zipfile.ZipFile(wheel) as zf:
        for rel in sorted(_resource_files()):
            name = "stereo_gui/_resources/" + rel.as_posix()
            assert name in zf.namelist(), f"{name} missing from {wheel.name}"
            assert zf.read(name) == (RESOURCES / rel).read_bytes()
        # the guide and its pictures, for Help > Technician's guide
        for path in sorted((REPO / "docs").glob("*.md")) + sorted((REPO / "docs").glob("*.png")):
            name = "stereo_gui/_docs/" + path.name
            assert name in zf.namelist(), f"{name} missing from {wheel.name}"


@pytest.fixture(scope="module")
def bundle() -> Path:
    """The bundle's executable, built first if it is absent (or if a rebuild is asked for)."""
    if not EXE.is_file() or os.environ.get("STEREO_GUI_BUNDLE_REBUILD") == "1":
        proc = subprocess.run(["bash", str(REPO / "packaging" / "build.sh")], cwd=REPO,
                              capture_output=True, text=True, timeout=3600)
        assert proc.returncode == 0, f"build failed:\n{proc.stdout[-3000:]}\n{proc.stderr[-3000:]}"
    assert EXE.is_file(), f"no executable at {EXE}"
    return EXE


def _run(args: list[str], env_extra: dict[str, str], timeout: float = 180,
         env_drop: tuple[str, ...] = ()):
    env = {k: v for k, v in os.environ.items() if k not in env_drop}
    env.update(env_extra)
    return subprocess.run(args, capture_output=True, text=True, env=env, timeout=timeout)


# what decides where Qt and PyOpenGL make their OpenGL contexts (X11, Wayland or none)
_DISPLAY_VARS = ("DISPLAY", "WAYLAND_DISPLAY", "XDG_SESSION_TYPE", "PYOPENGL_PLATFORM",
                 "QT_QPA_PLATFORM", "QT_XCB_GL_INTEGRATION")


def _smoke(args: list[str], check: str, env_extra: dict[str, str], tmp_path: Path) -> dict:
    """Run the bundle's smoke check `check` (packaging/smoke.py) and return its JSON report."""
    env = {"STEREO_GUI_BUNDLE_SMOKE": check,
           "STEREO_GUI_CONFIG_DIR": str(tmp_path / "config"),
           "STEREO_GUI_DATA_DIR": str(tmp_path / "data"), **env_extra}
    proc = _run(args, env, timeout=300, env_drop=_DISPLAY_VARS)
    output = proc.stdout + proc.stderr
    assert proc.returncode == 0, output[-3000:]
    assert "Traceback" not in output, output[-3000:]
    report = json.loads(proc.stdout.strip().splitlines()[-1])
    assert "error" not in report, report
    return report


@bundle_test
def test_version(bundle):
    proc = _run([str(bundle), "--version"], {})
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.strip() == f"stereo-gui {__version__}"


@bundle_test
def test_resources_sit_where_resources_py_looks(bundle):
    # stereo_gui/resources.py looks for `_resources` next to its own __file__, which in a
    # one-folder bundle is _internal/stereo_gui/.
    bundled = BUNDLE_DIR / "_internal" / "stereo_gui" / "_resources"
    assert (bundled / "icons" / "stereo-gui-256.png").is_file()
    wanted = _resource_files()
    have = {p.relative_to(bundled) for p in bundled.rglob("*") if p.is_file()}
    assert wanted <= have, f"missing in the bundle: {sorted(map(str, wanted - have))}"


@bundle_test
@pytest.mark.skipif(not _ON_LINUX, reason="Linux plugin names")
def test_qt_platform_plugins_are_bundled(bundle):
    platforms = BUNDLE_DIR / "_internal" / "PySide6" / "Qt" / "plugins" / "platforms"
    names = {p.name for p in platforms.iterdir()}
    assert {"libqoffscreen.so", "libqxcb.so"} <= names, names


@bundle_test
def test_gui_starts_offscreen_and_quits_by_itself(bundle, tmp_path):
    proc = _run([str(bundle)], {
        "QT_QPA_PLATFORM": "offscreen",
        "STEREO_GUI_QUIT_AFTER": "3",
        "STEREO_GUI_CONFIG_DIR": str(tmp_path / "config"),
    })
    output = proc.stdout + proc.stderr
    assert proc.returncode == 0, output[-3000:]
    assert "Traceback" not in output, output[-3000:]


@bundle_test
def test_live_pipeline_runs_in_the_bundle(bundle, tmp_path):
    # `bench` on the simulated rig runs the whole live pipeline: rectify, SGBM, and the WLS filter
    # of cv2.ximgproc (OpenCV contrib); presets come from the bundled resources.
    proc = _run([str(bundle), "bench", "--frames", "2", "--preset", "live", "--json"],
                {"STEREO_GUI_CONFIG_DIR": str(tmp_path / "config")})
    assert proc.returncode == 0, proc.stderr[-3000:]
    stages = json.loads(proc.stdout)["presets"]["live"]["stages_ms"]
    assert stages["wls"] > 0


@bundle_test
def test_bad_input_is_one_line_without_traceback(bundle, tmp_path):
    proc = _run([str(bundle), "bench", "--frames", "2", "--preset", "no-such-preset"],
                {"STEREO_GUI_CONFIG_DIR": str(tmp_path / "config")})
    assert proc.returncode == 2
    assert "Traceback" not in proc.stderr
    assert proc.stderr.strip().splitlines()[-1].startswith("stereo-gui: error:")


@bundle_test
def test_simulate_calibrate_measure_in_the_bundle(bundle, tmp_path):
    # the technician's headless chain, run by the bundled executable: a wall 1 m away measures 1 m
    env = {"STEREO_GUI_CONFIG_DIR": str(tmp_path / "config")}
    sim = tmp_path / "sim"
    proc = _run([str(bundle), "simulate", str(sim), "--pairs", "8", "--scene"], env)
    assert proc.returncode == 0, proc.stderr[-3000:]
    calib = tmp_path / "calib.yaml"
    proc = _run([str(bundle), "calibrate", str(sim), "-o", str(calib), "--json"], env)
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert json.loads(proc.stdout)["pairs_used"] == 8
    wall = next(s for s in json.loads((sim / "truth.json").read_text())["scenes"]
                if s.get("distance_mm") == 1000.0 and s["name"].startswith("wall"))
    proc = _run([str(bundle), "measure", "--calib", str(calib), str(sim / wall["left"]),
                 str(sim / wall["right"]), "--at", "320,240", "--json"], env)
    assert proc.returncode == 0, proc.stderr[-3000:]
    point = json.loads(proc.stdout)["points"][0]
    assert point["valid"]
    assert abs(point["Z_mm"] - 1000.0) < 10.0


@bundle_test
@pytest.mark.skipif(not _ON_LINUX, reason="the GTK theme plugin is a Linux one")
def test_gtk_theme_plugin_and_gtk_are_left_out(bundle):
    internal = BUNDLE_DIR / "_internal"
    assert not (internal / "PySide6" / "Qt" / "plugins" / "platformthemes" / "libqgtk3.so").exists()
    gtk = sorted(p.name for p in internal.rglob("*")
                 if p.name.startswith(("libgtk-3.so", "libgdk-3.so", "libpango-1.0.so")))
    assert not gtk, gtk
    # the other platform theme (XDG desktop portal, over D-Bus) stays
    assert (internal / "PySide6" / "Qt" / "plugins" / "platformthemes"
            / "libqxdgdesktopportal.so").is_file()


@bundle_test
@pytest.mark.skipif(not _ON_LINUX, reason="ELF libraries")
def test_every_library_a_bundled_binary_needs_is_bundled_or_left_to_the_system(bundle):
    # Nothing the bundle keeps may need a library the spec left out (with the GTK theme): every
    # DT_NEEDED name missing from the bundle must be one PyInstaller leaves to the system (libc,
    # libGL, libxcb, ...) or one it could not find on this build machine. PyInstaller's own
    # rules are asked in the build venv.
    python = BUILD_VENV / "bin" / "python"
    if not python.is_file():
        pytest.skip(f"no build venv at {BUILD_VENV} (STEREO_GUI_BUILD_VENV) to ask PyInstaller")
    elf = _bundled_elf_files()
    bundled = {p.name for p in (BUNDLE_DIR / "_internal").rglob("*")}
    missing = sorted({name for info in elf.values() for name in info.needed} - bundled)
    # the dynamic loader itself (ld-linux-x86-64.so.2, ld-linux-aarch64.so.1) is never bundled
    missing = [name for name in missing if not name.startswith(("ld-linux", "ld64.so"))]
    probe = ("import json, sys\n"
             "from PyInstaller.depend.dylib import include_library\n"
             "from PyInstaller.depend.bindepend import resolve_library_path\n"
             "names = json.load(sys.stdin)\n"
             "print(json.dumps([n for n in names\n"
             "                  if include_library(n) and resolve_library_path(n)]))\n")
    proc = subprocess.run([str(python), "-c", probe], input=json.dumps(missing),
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr[-3000:]
    left_out_wrongly = json.loads(proc.stdout)
    needers = {name: sorted(str(p.relative_to(BUNDLE_DIR)) for p, info in elf.items()
                            if name in info.needed) for name in left_out_wrongly}
    assert not left_out_wrongly, f"needed but not bundled: {needers}"


@bundle_test
@pytest.mark.skipif(not _ON_LINUX or shutil.which("strip") is None,
                    reason="debug sections are stripped on Linux when binutils' strip is installed")
def test_bundled_libraries_carry_no_debug_sections(bundle):
    elf = _bundled_elf_files()
    assert any(p.name.startswith("libpython3") for p in elf), "libpython not found in the bundle"
    with_debug = {str(p.relative_to(BUNDLE_DIR)): info.debug_bytes
                  for p, info in elf.items() if info.debug_bytes}
    assert not with_debug, with_debug


@bundle_test
def test_3d_view_without_an_opengl_context_says_why(bundle, tmp_path):
    # Offscreen and no display: Qt can make no OpenGL context, so the Live tab's 3D view window
    # opens with its note instead of a GL view (and nothing crashes). PyOpenGL and
    # pyqtgraph.opengl are imported all the same: the bundle must carry them.
    report = _smoke([str(bundle)], "cloud-view", {"QT_QPA_PLATFORM": "offscreen"}, tmp_path)
    assert report["platform"] == "offscreen"
    assert report["window_visible"]
    assert report["problem"] == "no OpenGL context can be made on this display", report
    assert not report["gl_view"]
    if _ON_LINUX:
        # GLX for X11 sessions, EGL for Wayland ones; osmesa, win32 and darwin are not needed
        assert report["opengl_platform_modules"] == ["glx", "egl"], report


_XVFB = shutil.which("xvfb-run")


@bundle_test
@pytest.mark.skipif(not _ON_LINUX or _XVFB is None, reason="needs Linux and xvfb-run (Xvfb)")
@pytest.mark.parametrize("session", ["x11", "wayland"])
def test_3d_view_draws_the_point_cloud_on_an_x_server(bundle, tmp_path, session):
    # Under Xvfb, Mesa's software renderer (llvmpipe, Debian/Ubuntu package libgl1-mesa-dri)
    # makes the context. "wayland": a Wayland session's PyOpenGL platform (EGL), here with Qt's
    # xcb platform making EGL contexts too, as Qt's wayland platform does.
    env = {"QT_QPA_PLATFORM": "xcb"}
    if session == "wayland":
        env.update(XDG_SESSION_TYPE="wayland", QT_XCB_GL_INTEGRATION="xcb_egl")
    report = _smoke([_XVFB, "-a", "-s", "-screen 0 1366x768x24", str(bundle)], "cloud-view",
                    env, tmp_path)
    if report.get("problem"):
        pytest.skip(f"no OpenGL on this Xvfb (install Mesa's DRI drivers): {report['problem']}")
    platform = {"x11": "OpenGL.platform.glx", "wayland": "OpenGL.platform.egl"}[session]
    assert report["opengl_platform"] == platform, report
    assert report["points"] > 10000, report  # the simulated rig's scene, every other pixel
    # drawn: the cloud covered 17 % of the frame buffer in 2236 colours here; the grid and axes
    # alone (a cloud that never reached OpenGL) cover 2.5 % in 86 (antialiased lines)
    assert report["colours"] > 500 and report["drawn_fraction"] > 0.08, report
