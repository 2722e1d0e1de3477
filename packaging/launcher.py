"""Entry script of the PyInstaller bundle: the same as the installed `stereo-gui` command.

`STEREO_GUI_BUNDLE_SMOKE=NAME` runs one of the bundle's smoke checks instead (packaging/smoke.py,
used by tests/test_bundle.py).
"""

import multiprocessing
import os
import sys

from stereo_gui.cli import main

if __name__ == "__main__":
    # A frozen Windows executable re-runs itself for child processes; this keeps them from
    # starting a second window if anything below ever uses multiprocessing.
    multiprocessing.freeze_support()
    smoke = os.environ.get("STEREO_GUI_BUNDLE_SMOKE")
    if smoke:
        import smoke as smoke_checks  # packaging/smoke.py, bundled by stereo-gui.spec

        sys.exit(smoke_checks.main(smoke))
    sys.exit(main())
