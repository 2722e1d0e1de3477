"""The job vocabulary under the names the Qt workers import: everything is defined once, in
`stereo_gui.core.jobs` (see there for what a job is); `JobCancelled` is its `Cancelled`."""

from __future__ import annotations

from stereo_gui.core.jobs import Cancelled, Job, JobControl, Progress

JobCancelled = Cancelled

__all__ = ["Job", "JobCancelled", "JobControl", "Progress"]
