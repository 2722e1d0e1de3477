"""The error bar keeps every problem until it is dismissed, shows the newest, lists them all."""

from __future__ import annotations

import pytest

from stereo_gui.qt.widgets.error_bar import MAX_KEPT, ErrorBar


@pytest.fixture
def bar(qtbot):
    """An error bar in a shown window (the bar itself starts hidden)."""
    from PySide6.QtWidgets import QVBoxLayout, QWidget

    window = QWidget()
    qtbot.addWidget(window)
    bar = ErrorBar()
    QVBoxLayout(window).addWidget(bar)
    window.show()
    yield bar
    window.close()


def test_several_messages_are_kept_and_the_newest_shown(bar):
    assert not bar.isVisible() and bar.messages() == []
    bar.show_text("the log was set aside")
    assert bar.isVisible() and bar.label.text() == "the log was set aside"
    assert not bar.all_button.isVisible()  # one problem: nothing more to open
    bar.show_text("the settings were set aside")
    bar.show_text("the source cannot be opened")
    assert bar.messages() == ["the log was set aside", "the settings were set aside",
                              "the source cannot be opened"]
    assert bar.label.text() == "the source cannot be opened"
    assert bar.all_button.isVisible() and bar.all_button.text() == "All 3 problems"
    assert not bar.list.isVisible()
    bar.all_button.click()
    assert bar.list.isVisible()
    assert [bar.list.item(i).text() for i in range(bar.list.count())] == bar.messages()


def test_a_message_said_again_moves_to_the_end_once(bar):
    for text in ("a", "b", "a"):
        bar.show_text(text)
    assert bar.messages() == ["b", "a"] and bar.label.text() == "a"


def test_a_problem_that_ended_goes_and_the_others_stay(bar):
    bar.show_text("the preset is broken")
    bar.show_text("the left camera stopped")
    bar.remove("the left camera stopped")
    assert bar.isVisible() and bar.messages() == ["the preset is broken"]
    assert bar.label.text() == "the preset is broken" and not bar.all_button.isVisible()
    bar.remove("the preset is broken")
    assert not bar.isVisible()


def test_dismiss_clears_them_all(bar):
    bar.show_text("a")
    bar.show_text("b")
    bar.all_button.click()
    bar.clear()
    assert not bar.isVisible() and bar.messages() == [] and not bar.all_button.isChecked()
    bar.show_text("c")
    assert bar.isVisible() and not bar.list.isVisible()


def test_the_list_keeps_the_newest(bar):
    for i in range(MAX_KEPT + 7):
        bar.show_text(f"problem {i}")
    assert len(bar.messages()) == MAX_KEPT and bar.messages()[-1] == f"problem {MAX_KEPT + 6}"
    assert bar.messages()[0] == "problem 7"
