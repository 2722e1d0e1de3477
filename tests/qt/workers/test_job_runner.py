"""The job runner: results and failures come back by signal with the job's id."""

from __future__ import annotations

from stereo_gui.qt.workers.job_runner import JobRunner


def test_job_runner_delivers_results_with_ids(qtbot):
    jobs = JobRunner()
    try:
        with qtbot.waitSignal(jobs.finished, timeout=30000) as sig:
            job_id = jobs.submit(lambda: 6 * 7)
        assert sig.args == [job_id, 42]
        with qtbot.waitSignal(jobs.failed, timeout=30000) as sig:
            bad_id = jobs.submit(lambda: 1 / 0)
        assert sig.args[0] == bad_id and "division" in sig.args[1]
    finally:
        assert jobs.stop(2000)
