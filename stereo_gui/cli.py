"""The command line: the GUI by default, and headless subcommands.

Every subcommand lives in its own module under `stereo_gui.commands` with two functions,
`add_arguments(parser)` and `run(args) -> int`. A `StereoGuiError` raised anywhere below becomes
one line on stderr and exit status 2, never a traceback.
"""

from __future__ import annotations

import argparse
import contextlib
import errno
import importlib
import logging
import os
import signal
import sys
import threading
from collections.abc import Iterator
from types import FrameType, ModuleType

from stereo_gui import __version__
from stereo_gui.core.errors import StereoGuiError

TYPE_CHECKING = False  # (not typing's: `import typing` would add ~3 ms to `stereo-gui --help`)
if TYPE_CHECKING:
    from typing import NoReturn

# name -> (module, one-line help)
SUBCOMMANDS: dict[str, tuple[str, str]] = {
    "calibrate": ("stereo_gui.commands.calibrate", "calibrate a stereo rig from target pairs"),
    "measure": ("stereo_gui.commands.measure", "measure distances at pixels of a stereo pair"),
    "disparity": ("stereo_gui.commands.disparity", "write the disparity map of a stereo pair"),
    "bench": ("stereo_gui.commands.bench", "measure the speed of the live pipeline"),
    "simulate": ("stereo_gui.commands.simulate", "write images from the simulated stereo rig"),
    "target": ("stereo_gui.commands.target", "write a printable calibration target (PDF, SVG, PNG)"),
    "serve": ("stereo_gui.commands.serve", "stream the live depth to robots' programs (Foxglove, MCAP)"),
    "ros2-bag": ("stereo_gui.commands.ros2_bag", "write the depth as a ROS 2 bag (rosbag2, MCAP storage)"),
}


PREFIX = "stereo-gui"  # every line the command line writes to stderr starts "stereo-gui: ..."


class _Parser(argparse.ArgumentParser):
    """An argument parser whose usage errors exit with status 2 and one clear line, with the
    same prefix as every other error ("stereo-gui: error: calibrate: ...")."""

    def error(self, message: str) -> NoReturn:  # noqa: D401 - argparse API
        if "expected one argument" in message:
            # `--at -1,5`: argparse takes a value that starts with "-" for an option
            message += (" (a value that starts with '-' must be attached with '=', as in "
                        "--at=-1,5)")
        sub = self.prog[len(PREFIX):].strip()
        where = f"{sub}: " if sub else ""
        _say(f"{PREFIX}: error: {where}{message} (see {self.prog} --help)\n")
        raise SystemExit(2)


def _gui_parser() -> argparse.ArgumentParser:
    width = max(map(len, SUBCOMMANDS))
    p = _Parser(
        prog="stereo-gui",
        description="Stereo GUI: calibrate a two-webcam stereo camera and read distances off a\n"
        "live depth view. Without a subcommand it starts the application window.",
        epilog="subcommands (stereo-gui SUBCOMMAND --help for their options):\n"
        + "\n".join(f"  {name:<{width}}  {text}" for name, (_, text) in SUBCOMMANDS.items()),
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("--version", action="version", version=f"stereo-gui {__version__}")
    p.add_argument(
        "--source",
        default=None,
        help="auto (default: cameras if found, else the simulated rig), sim, cams:L,R, sbs:N, "
        "a folder of recorded pairs, or a side-by-side video file",
    )
    p.add_argument("--calib", default=None, metavar="FILE",
                   help="calibration file to load at start-up")
    p.add_argument("-v", "--verbose", action="store_true", help="log more detail")
    return p


def _sub_parser(name: str) -> tuple[argparse.ArgumentParser, ModuleType]:
    module_name, help_text = SUBCOMMANDS[name]
    module = importlib.import_module(module_name)
    p = _Parser(prog=f"stereo-gui {name}", description=help_text)
    p.add_argument("-v", "--verbose", action="store_true", help="log more detail")
    module.add_arguments(p)
    return p, module


class _UserFormatter(logging.Formatter):
    """Warnings and errors as a user reads them: "stereo-gui: warning: ...", the prefix of
    every message the command line writes (with -v: level and logger name, for developers)."""

    def format(self, record: logging.LogRecord) -> str:
        text = super().format(record)
        return f"{PREFIX}: {record.levelname.lower()}: {text}"


def setup_logging(verbose: bool) -> None:
    """Messages as the command line shows them: warnings and errors in the user's words under
    one prefix; with `verbose`, every level with the logger's name."""
    if verbose:
        logging.basicConfig(level=logging.DEBUG, format="%(levelname)s %(name)s: %(message)s")
    else:
        handler = logging.StreamHandler()
        handler.setFormatter(_UserFormatter("%(message)s"))
        logging.basicConfig(level=logging.WARNING, handlers=[handler])
    quiet_opencv(verbose)


def quiet_opencv(verbose: bool = False) -> None:
    """Keep OpenCV's own "[ WARN:0@0.05] global cap_v4l.cpp..." lines off the user's terminal:
    our messages say what went wrong in the user's words. With --verbose they are shown."""
    import cv2  # here, not at the top: OpenCV takes ~100 ms to load, `--help` ~10 ms in all

    cv2.utils.logging.setLogLevel(cv2.utils.logging.LOG_LEVEL_WARNING if verbose
                                  else cv2.utils.logging.LOG_LEVEL_SILENT)


def _say(text: str) -> None:
    """A line on stderr, if there is one to write to (a closed or full stderr says nothing)."""
    try:
        sys.stderr.write(text)
        sys.stderr.flush()
    except (OSError, ValueError, AttributeError):
        pass


def _stdout_gone() -> None:
    """The reader of our output left (`stereo-gui calibrate --json | head -1`): what is still
    buffered goes nowhere, and the exit is quiet."""
    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
    except (OSError, ValueError, AttributeError):
        pass


def main(argv: list[str] | None = None) -> int:
    """Run the command line; return the process exit status."""
    argv = list(sys.argv[1:] if argv is None else argv)
    # started with a standard stream closed (`2>&-`): Python leaves it None, and every line
    # written to it would end the command with an AttributeError
    if sys.stderr is None:
        sys.stderr = open(os.devnull, "w")  # noqa: SIM115 - for the process's lifetime
    if sys.stdout is None:
        sys.stdout = open(os.devnull, "w")  # noqa: SIM115
    try:
        return _main(argv)
    except BrokenPipeError:
        _stdout_gone()
        return 0
    except OSError as exc:
        if exc.errno not in (errno.ENOSPC, errno.EIO, errno.EDQUOT):
            raise
        # the output (a redirection to a full disk or /dev/full): said, not a traceback
        _stdout_gone()
        _say(f"{PREFIX}: error: cannot write the output: {os.strerror(exc.errno)}\n")
        return 2


@contextlib.contextmanager
def _terminated_as_interrupted() -> Iterator[None]:
    """SIGTERM raises KeyboardInterrupt while a command runs (in the main thread), so that what
    is being written is cleaned up as after Ctrl+C: no temporary file is left behind."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def interrupt(signum: int, frame: FrameType | None) -> NoReturn:
        raise KeyboardInterrupt

    previous = signal.signal(signal.SIGTERM, interrupt)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)


def _window_bench(args: argparse.Namespace) -> int:
    """`bench --window`: the options checked without Qt, then the window (Qt, so it is run
    from here, the one layer above both), offscreen when there is no display."""
    from stereo_gui.commands.bench_window import window_request, write_result

    request = window_request(args)
    from stereo_gui.qt.preflight import check_gui_can_start, offscreen_without_display

    offscreen_without_display()
    check_gui_can_start()
    from stereo_gui.qt.window_bench import run_window_bench  # Qt: only on this path

    write_result(run_window_bench(request), args.json)
    return 0


def _main(argv: list[str]) -> int:
    try:
        if argv and argv[0] in SUBCOMMANDS:
            parser, module = _sub_parser(argv[0])
            args = parser.parse_args(argv[1:])
            setup_logging(args.verbose)
            if argv[0] == "bench" and args.window is not None:
                code = _window_bench(args)
                sys.stdout.flush()
                return code
            with _terminated_as_interrupted():
                code = int(module.run(args) or 0)
            sys.stdout.flush()  # (a full or closed output is said here, not at exit)
            return code
        args = _gui_parser().parse_args(argv)
        setup_logging(args.verbose)
        # the GUI's path only: preflight (ctypes, subprocess: ~8 ms) and Qt stay off the
        # subcommands' and --help's way
        from stereo_gui.qt.preflight import check_gui_can_start

        check_gui_can_start()  # no display or a missing Qt library: one line, not Qt's abort
        from stereo_gui.qt.app import run_app  # Qt is imported only for the GUI

        return run_app(source=args.source, calib=args.calib)
    except StereoGuiError as exc:
        _say(f"{PREFIX}: error: {exc}\n")
        return 2
    except KeyboardInterrupt:
        _say(f"{PREFIX}: interrupted\n")
        return 130
