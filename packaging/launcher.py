"""Entry script of the PyInstaller bundle: the same as the installed `stereo-gui` command."""

import multiprocessing
import sys

from stereo_gui.cli import main

if __name__ == "__main__":
    # A frozen Windows executable re-runs itself for child processes; this keeps them from
    # starting a second window if anything below ever uses multiprocessing.
    multiprocessing.freeze_support()
    sys.exit(main())
