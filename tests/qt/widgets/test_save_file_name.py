"""A file to save in a folder that does not exist yet: the folder is offered for creation, as
the session and recording folder dialogs do, instead of a red bar after the dialog."""

from __future__ import annotations

from PySide6.QtWidgets import QFileDialog, QMessageBox

from stereo_gui.qt.widgets.folder_dialog import save_file_name


def test_a_new_folder_is_made_when_the_person_says_yes(qtbot, monkeypatch, questions, tmp_path):
    target = tmp_path / "new" / "deeper" / "log.xlsx"
    monkeypatch.setattr(QFileDialog, "getSaveFileName",
                        lambda *a, **k: (str(target), "Workbooks (*.xlsx)"))
    assert save_file_name(None, "Export", str(tmp_path)) == (str(target), "Workbooks (*.xlsx)")
    assert target.parent.is_dir() and "new" in questions.asked[-1]


def test_no_leaves_nothing_made_and_nothing_chosen(qtbot, monkeypatch, questions, tmp_path):
    target = tmp_path / "new" / "log.xlsx"
    monkeypatch.setattr(QFileDialog, "getSaveFileName", lambda *a, **k: (str(target), ""))
    questions.reply = QMessageBox.StandardButton.No
    assert save_file_name(None, "Export") == ("", "")
    assert not (tmp_path / "new").exists()


def test_an_existing_folder_asks_nothing(qtbot, monkeypatch, questions, tmp_path):
    target = tmp_path / "log.xlsx"
    monkeypatch.setattr(QFileDialog, "getSaveFileName", lambda *a, **k: (str(target), ""))
    assert save_file_name(None, "Export") == (str(target), "")
    assert questions.asked == []
    monkeypatch.setattr(QFileDialog, "getSaveFileName", lambda *a, **k: ("", ""))
    assert save_file_name(None, "Export") == ("", "")  # cancelled


def test_a_folder_that_cannot_be_made_is_said(qtbot, monkeypatch, questions, tmp_path):
    (tmp_path / "file").write_text("x")
    target = tmp_path / "file" / "sub" / "log.xlsx"  # under a file: cannot be a folder
    monkeypatch.setattr(QFileDialog, "getSaveFileName", lambda *a, **k: (str(target), ""))
    warned = []
    monkeypatch.setattr(QMessageBox, "warning", lambda _p, _t, text, *a: warned.append(text))
    assert save_file_name(None, "Export") == ("", "")
    assert warned and "Cannot create" in warned[0]
