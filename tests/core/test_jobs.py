"""Job progress and cancel, how a job is run and where it stands, without Qt."""

import threading

import pytest

from stereo_gui.core.errors import InputError
from stereo_gui.core.jobs import (
    JOB_MOVES,
    Cancelled,
    JobControl,
    JobState,
    JobTicket,
    Progress,
    check_cancel,
    is_cancelled,
    run_job,
)
from stereo_gui.core.states import TransitionError


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


# ---- running a job, and where it stands --------------------------------------------------------
def test_a_jobs_state_moves_only_forward_and_ends_once():
    real = {(JobState.QUEUED, JobState.RUNNING), (JobState.QUEUED, JobState.CANCELLED),
            (JobState.RUNNING, JobState.FINISHED), (JobState.RUNNING, JobState.FAILED),
            (JobState.RUNNING, JobState.CANCELLED)}
    for a in JobState:
        for b in JobState:
            assert JOB_MOVES.allows(a, b) == ((a, b) in real), (a, b)


def test_a_ticket_refuses_an_impossible_move_and_tells_waiters_when_it_ended():
    ticket = JobTicket(7, JobControl())
    with pytest.raises(TransitionError):
        ticket.move(JobState.FINISHED)  # it never ran
    ticket.move(JobState.RUNNING)
    assert not ticket.ended and not ticket.wait(0.01)
    threading.Timer(0.05, ticket.move, (JobState.FAILED,)).start()
    assert ticket.wait(30) and ticket.ended and ticket.state is JobState.FAILED
    with pytest.raises(TransitionError):
        ticket.move(JobState.FINISHED)  # a job ends once


def _steps(n, seen=None):
    def job(control):
        for i in range(n):
            if seen is not None:
                seen.append(i)
            yield Progress(i, n, f"step {i}")
        return "done"
    return job


def test_run_job_passes_a_generators_progress_on_and_returns_its_result():
    seen = []
    end = run_job(_steps(3), JobControl(seen.append))
    assert (end.state, end.result, end.error) == (JobState.FINISHED, "done", None)
    assert [p.text for p in seen] == ["step 0", "step 1", "step 2"]
    assert run_job(lambda control: 42, JobControl()).result == 42  # a job of one step


def test_run_job_stops_a_generator_at_its_next_step_once_cancel_is_asked():
    ran = []
    control = JobControl(lambda p: control.set() if p.done == 1 else None)
    assert run_job(_steps(100, ran), control).state is JobState.CANCELLED
    assert ran == [0, 1]
    asked_before = JobControl()
    asked_before.set()
    assert run_job(_steps(3, ran := []), asked_before).state is JobState.CANCELLED
    assert ran == []  # never started


def test_run_job_turns_errors_into_ends():
    def failing(control):
        yield Progress(0, 1)
        raise ValueError("boom")

    end = run_job(failing, JobControl())
    assert end.state is JobState.FAILED and isinstance(end.error, ValueError)

    def core_cancelled(control):
        check_cancel(lambda: True)  # the core's own Cancelled

    assert run_job(core_cancelled, JobControl()).state is JobState.CANCELLED
    control = JobControl()

    def error_after_cancel(control):
        control.set()
        raise InputError("the folder went away")  # on its way out after cancel: a cancel

    assert run_job(error_after_cancel, control).state is JobState.CANCELLED


def test_a_job_of_one_step_asked_to_stop_while_it_runs_keeps_its_result():
    def one_step(control):
        control.set()  # cancel asked while it runs: it cannot stop, its result stands
        return "written"

    end = run_job(one_step, JobControl())
    assert (end.state, end.result) == (JobState.FINISHED, "written")
