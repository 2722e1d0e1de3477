"""Job progress and cancel without Qt."""

import pytest

from stereo_gui.pipeline.jobs import JobCancelled, JobControl, Progress


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
    with pytest.raises(JobCancelled):
        control.check()
