"""Job progress and cancel without Qt."""

import threading

import pytest

from stereo_gui.core.jobs import Cancelled, JobControl, Progress, check_cancel, is_cancelled


def test_progress_percent():
    assert Progress(1, 4).percent == 25
    assert Progress(0, 0).percent == 0


def test_control_reports_progress_and_cancels():
    seen = []
    control = JobControl(seen.append)
    control.report(2, 5, "step")
    assert seen == [Progress(2, 5, "step")]
    assert not control() and not control.is_set()
    control.check()
    control.set()
    assert control() and control.is_set()
    with pytest.raises(Cancelled):
        control.check()


@pytest.mark.parametrize("make", [threading.Event, lambda: JobControl()])
def test_an_event_or_a_control_cancels_core_work(make):
    cancel = make()
    assert not is_cancelled(cancel) and not is_cancelled(None)
    check_cancel(cancel)
    cancel.set()
    assert is_cancelled(cancel)
    with pytest.raises(Cancelled):
        check_cancel(cancel)
