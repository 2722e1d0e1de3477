"""The About dialog: what the application is, its version and the versions of what it runs on.

`show_about(parent)` is what Help > About calls. The text is built by `about_html()` so it can be
checked without a window, and `versions()` is what a technician copies into a bug report.
"""

from __future__ import annotations

import platform
import sys

import cv2
import numpy
import pyqtgraph
import PySide6
from PySide6.QtCore import Qt, qVersion
from PySide6.QtGui import QGuiApplication, QIcon
from PySide6.QtWidgets import (
    QDialog,
    QDialogButtonBox,
    QHBoxLayout,
    QLabel,
    QPushButton,
    QVBoxLayout,
    QWidget,
)

from stereo_gui import __version__
from stereo_gui.resources import resource_path

DESCRIPTION = (
    "Calibrate a two-webcam stereo camera with a chessboard and read distances off a live "
    "depth view by clicking on it."
)
LICENCE = "MIT licence"
ICON_SIZES = (16, 24, 32, 48, 64, 128, 256)


def versions() -> dict[str, str]:
    """Versions of the application and of the libraries it runs on, by name."""
    return {
        "Stereo GUI": __version__,
        "Python": platform.python_version(),
        "OpenCV": cv2.__version__,
        "Qt": qVersion(),
        "PySide6": PySide6.__version__,
        "numpy": numpy.__version__,
        "pyqtgraph": pyqtgraph.__version__,
        "System": f"{platform.system()} {platform.release()} ({platform.machine()})",
        # PyInstaller sets sys.frozen in a bundle; a plain interpreter has no such attribute
        "Bundled": "yes" if getattr(sys, "frozen", False) else "no",
    }


def versions_text() -> str:
    """The versions as plain lines `name: version`, for the clipboard."""
    return "\n".join(f"{k}: {v}" for k, v in versions().items())


def about_html() -> str:
    """The dialog's text as Qt rich text."""
    rows = "".join(
        f"<tr><td>{name}</td><td>&nbsp;&nbsp;{value}</td></tr>"
        for name, value in versions().items()
        if name != "Stereo GUI"
    )
    return (
        f"<h2>Stereo GUI {__version__}</h2>"
        f"<p>{DESCRIPTION}</p>"
        "<p>Without cameras it runs on a simulated stereo rig (two distorted cameras 110 mm apart), "
        "which is also the ground truth of its tests.</p>"
        f"<table>{rows}</table>"
        f"<p>{LICENCE}. Built on OpenCV (Apache 2.0), Qt for Python (LGPLv3), numpy, pyqtgraph "
        "and openpyxl.</p>"
    )


def application_icon() -> QIcon:
    """The application icon with every PNG size shipped in resources/icons (empty if missing)."""
    icon = QIcon()
    for size in ICON_SIZES:
        path = resource_path("icons", f"stereo-gui-{size}.png")
        if path.is_file():
            icon.addFile(str(path))
    return icon


class AboutDialog(QDialog):
    """A small dialog with the icon, the text of `about_html()`, Copy versions and Close."""

    def __init__(self, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.setWindowTitle("About Stereo GUI")
        icon = application_icon()
        self.setWindowIcon(icon)

        self.icon_label = QLabel()
        self.icon_label.setPixmap(icon.pixmap(96, 96))
        self.icon_label.setAlignment(Qt.AlignmentFlag.AlignTop)
        self.text_label = QLabel(about_html())
        self.text_label.setTextFormat(Qt.TextFormat.RichText)
        self.text_label.setWordWrap(True)
        self.text_label.setTextInteractionFlags(Qt.TextInteractionFlag.TextSelectableByMouse)
        self.text_label.setMinimumWidth(380)

        buttons = QDialogButtonBox(QDialogButtonBox.StandardButton.Close)
        self.copy_button = QPushButton("Copy versions")
        buttons.addButton(self.copy_button, QDialogButtonBox.ButtonRole.ActionRole)
        self.copy_button.clicked.connect(self.copy_versions)
        buttons.rejected.connect(self.reject)

        top = QHBoxLayout()
        top.addWidget(self.icon_label)
        top.addWidget(self.text_label, 1)
        layout = QVBoxLayout(self)
        layout.addLayout(top)
        layout.addWidget(buttons)

    def copy_versions(self) -> None:
        """Put the versions on the clipboard, for a bug report."""
        QGuiApplication.clipboard().setText(versions_text())


def show_about(parent: QWidget | None = None) -> AboutDialog:
    """Open the About dialog (window-modal, not blocking) and return it.

    With a parent, Qt owns the dialog and deletes it when closed; without one the caller must keep
    the returned reference while it is shown.
    """
    dialog = AboutDialog(parent)
    if parent is not None:
        dialog.setAttribute(Qt.WidgetAttribute.WA_DeleteOnClose)
    dialog.open()
    return dialog
