#!/usr/bin/env python
"""The guide's picture of the parameter panel with the live preset on the simulated rig's true
calibration: docs/guide-parameters.png (offscreen; no display needed).

    python scripts/screenshot_parameters.py [--out docs]
"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--out", type=Path, default=REPO / "docs")
    args = ap.parse_args()
    os.environ.setdefault("QT_QPA_PLATFORM", "offscreen")
    from PySide6.QtWidgets import QApplication

    app = QApplication(sys.argv)
    from stereo_gui.qt.widgets.params_panel import ParamsPanel
    from stereo_gui.sources.sim import SimRig

    panel = ParamsPanel()
    panel.set_calibration(SimRig(seed=0).true_calibration())
    panel.apply_preset("live")
    panel.resize(328, panel.sizeHint().height())
    panel.show()
    app.processEvents()
    path = args.out / "guide-parameters.png"
    panel.grab().save(str(path))
    print(f"wrote {path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
