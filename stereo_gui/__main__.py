"""`python -m stereo_gui` is the same as the `stereo-gui` command."""

import sys

from stereo_gui.cli import main

sys.exit(main())
