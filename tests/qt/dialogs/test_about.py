"""The About dialog: version, library versions, icon, and the clipboard copy."""

from __future__ import annotations

import cv2
import numpy
from PySide6.QtCore import qVersion
from PySide6.QtGui import QGuiApplication
from PySide6.QtWidgets import QWidget

from stereo_gui import __version__
from stereo_gui.qt.dialogs.about import AboutDialog, about_html, application_icon, show_about, versions


def test_versions_name_the_real_libraries():
    v = versions()
    assert v["Stereo GUI"] == __version__
    assert v["OpenCV"] == cv2.__version__
    assert v["numpy"] == numpy.__version__
    assert v["Qt"] == qVersion()
    assert v["Bundled"] == "no"


def test_text_has_version_description_and_licence():
    html = about_html()
    assert f"Stereo GUI {__version__}" in html
    assert cv2.__version__ in html
    assert "MIT" in html
    assert "stereo camera" in html


def test_icon_has_every_shipped_size(qtbot):
    icon = application_icon()
    assert not icon.isNull()
    sizes = {s.width() for s in icon.availableSizes()}
    assert {16, 32, 48, 256} <= sizes


def test_show_about_opens_a_dialog_owned_by_its_parent(qtbot):
    parent = QWidget()
    qtbot.addWidget(parent)
    dialog = show_about(parent)
    assert isinstance(dialog, AboutDialog)
    assert dialog.isVisible()
    assert dialog.parent() is parent
    assert __version__ in dialog.text_label.text()
    assert not dialog.icon_label.pixmap().isNull()
    dialog.copy_button.click()
    assert f"Stereo GUI: {__version__}" in QGuiApplication.clipboard().text()
    dialog.close()
