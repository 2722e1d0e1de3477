"""The Live tab's marker labels: a few words for every reason a reading has no distance."""

from __future__ import annotations

from stereo_gui.core.measure import Reason
from stereo_gui.qt.tabs.live_readings import short_reason


def test_every_reason_has_a_short_label():
    for reason in Reason:
        label = short_reason(reason)
        assert label and len(label) <= 16, reason
    assert short_reason(Reason.NOT_SEEN) == "not seen"
    assert short_reason(Reason.NO_VALID_PIXELS) == "no match"


def test_a_reason_read_back_as_text_gets_the_same_label():
    for reason in Reason:
        assert short_reason(str(reason)) == short_reason(reason)


def test_no_reason_and_unknown_texts():
    assert short_reason(None) == short_reason("") == "invalid"
    assert short_reason("lens cap on") == "lens cap on"
    assert short_reason("a reason of a newer version") == "a reason of a n…"
