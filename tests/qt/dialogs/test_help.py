"""Help: the technician's guide in a window, the keyboard shortcuts, where files are kept."""

from __future__ import annotations

from PySide6.QtCore import QUrl
from PySide6.QtWidgets import QApplication

from stereo_gui.qt.dialogs.help import (
    FoldersDialog,
    GuideWindow,
    ShortcutsDialog,
    heading_slug,
    kept_folders,
    shortcut_rows,
)


def test_help_menu_opens_the_guide_with_its_pictures_and_sections(qtbot, window):
    texts = [a.text() for a in window.menuBar().actions()[-1].menu().actions() if a.text()]
    assert texts == ["Technician's &guide", "&Keyboard shortcuts", "&Where files are kept",
                     "&About Stereo GUI"]
    assert window.help_actions["guide"].shortcut().toString() == "F1"
    window.help_actions["guide"].trigger()
    guide = next(w for w in QApplication.topLevelWidgets()
                 if isinstance(w, GuideWindow) and w.isVisible())
    qtbot.addWidget(guide)
    headings = guide.headings()
    assert "3. Capture a calibration set" in headings and "13. Where files go" in headings
    # the pictures are read from beside the guide, shrunk to a reading width
    doc = guide.browser.document()
    assert "guide-start.png" in guide.browser.toHtml()
    image = doc.resource(doc.ResourceType.ImageResource.value, QUrl("guide-start.png"))
    assert image is not None and not image.isNull()
    # a link of the contents moves to its section
    guide.browser.anchorClicked.emit(QUrl("#6-the-live-view-and-its-parameters"))
    assert guide.browser.textCursor().block().text() == "6. The live view and its parameters"
    assert not guide.show_section("no-such-section")
    guide.close()


def test_heading_slugs_are_githubs():
    assert heading_slug("3. Capture a calibration set") == "3-capture-a-calibration-set"
    assert heading_slug("Calibration health: did the cameras move?") == \
        "calibration-health-did-the-cameras-move"


def test_the_shortcuts_list_the_menus_own_and_the_others(qtbot, window):
    rows = shortcut_rows(window)
    dialog = ShortcutsDialog(rows, window)
    qtbot.addWidget(dialog)
    shown = dict(dialog.rows())
    assert shown["Ctrl+Shift+O"] == "Choose source"
    assert shown["Ctrl+O"] == "Open calibration"
    assert shown["F1"] == "Technician's guide"
    assert "pause" in shown["Space"] and "save the pair" in shown["S"]


def test_where_files_are_kept_names_the_settings_and_data_folders(qtbot, window, tmp_path,
                                                                     monkeypatch):
    import os
    from pathlib import Path

    folders = dict(kept_folders(window.ctx.settings))
    assert folders["Settings (settings.json)"] == Path(os.environ["STEREO_GUI_CONFIG_DIR"])
    assert folders["The measurement log kept between runs (measurement-log.json)"] == Path(
        os.environ["STEREO_GUI_DATA_DIR"])
    assert folders["Your presets"] == Path(os.environ["STEREO_GUI_CONFIG_DIR"]) / "presets"
    dialog = FoldersDialog(list(folders.items()), window)
    qtbot.addWidget(dialog)
    assert dialog.paths == folders


def test_open_without_a_file_manager_says_so_and_copies_the_path(qtbot, window, tmp_path,
                                                                 monkeypatch):
    from PySide6.QtGui import QGuiApplication

    from stereo_gui.qt.dialogs import help as help_dialog

    dialog = FoldersDialog([("Settings", tmp_path)], window)
    qtbot.addWidget(dialog)
    monkeypatch.setattr(help_dialog, "file_manager_missing", lambda: True)
    assert not dialog.open_in_file_manager(tmp_path)
    assert "No file manager" in dialog.said.text() and str(tmp_path) in dialog.said.text()
    assert QGuiApplication.clipboard().text() == str(tmp_path)
    opened = []
    monkeypatch.setattr(help_dialog, "file_manager_missing", lambda: False)
    monkeypatch.setattr(help_dialog.QDesktopServices, "openUrl",
                        lambda url: opened.append(url.toLocalFile()) or True)
    assert dialog.open_in_file_manager(tmp_path)
    assert opened == [str(tmp_path)] and dialog.said.text().startswith("Opening")


def test_no_folder_application_counts_as_no_file_manager(monkeypatch):
    import subprocess

    from stereo_gui.qt.dialogs import help as help_dialog

    monkeypatch.setattr(help_dialog.sys, "platform", "linux")
    monkeypatch.setattr(help_dialog.shutil, "which", lambda name: None)
    assert help_dialog.file_manager_missing()
    monkeypatch.setattr(help_dialog.shutil, "which", lambda name: f"/usr/bin/{name}")
    monkeypatch.setattr(help_dialog.subprocess, "run", lambda *a, **k: subprocess.CompletedProcess(
        a, 0, stdout="\n", stderr=""))
    assert help_dialog.file_manager_missing()
    monkeypatch.setattr(help_dialog.subprocess, "run", lambda *a, **k: subprocess.CompletedProcess(
        a, 0, stdout="org.gnome.Nautilus.desktop\n", stderr=""))
    assert not help_dialog.file_manager_missing()
