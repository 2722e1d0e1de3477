"""The QThreads every worker runs in, made so that they never take the process down.

A QThread destroyed while it runs aborts the process ("QThread: Destroyed while thread is still
running"), and a camera read or an OpenCV call cannot be interrupted: it can outlast the 2 s the
window waits at closing. So:
- a WorkerThread has no parent, and every started one is referenced from this module until it
  has finished (a queued `finished` to the main thread, or a successful `join`, drops it):
  neither Python's garbage collector nor a parent's destructor deletes it while it runs,
  whoever dropped their reference;
- `join(timeout_ms)` waits at most that long and never more; a thread still running then is
  left to end on its own (it ends when its blocked call returns and it sees it was asked to stop);
- at interpreter exit PySide deletes the QObjects Python owns, running threads included, which
  would abort. `_at_exit` runs before that (an `atexit` handler; PySide cleans up later, from
  Py_AtExit): it asks every live thread to stop and waits up to EXIT_WAIT_MS for them; one
  still blocked then is handed over to C++ (parented to a pair of keeper objects that parent
  each other, so nothing ever deletes them, nor the thread) and the process ends with it, with
  its own exit status. `stereo_gui.qt.app.run_app` does not wait for that: it leaves with
  os._exit when its workers did not stop.

Threads run at a lower priority on Linux (niceness WORKER_NICE, per thread): under CPU load the
UI thread wins. On 2 CPUs OpenCV starts no pool of its own in the application
(`pipeline.concurrency`): its calls run in, and at the niceness of, the
thread that makes them.
"""

from __future__ import annotations

import atexit
import logging
import threading
import time
from collections.abc import Callable

from PySide6.QtCore import QObject, QThread, Slot

from stereo_gui.pipeline.concurrency import lower_thread_priority

log = logging.getLogger(__name__)

WORKER_NICE = 10  # Linux niceness of worker threads: under CPU load the UI thread wins
EXIT_WAIT_MS = 1000  # at interpreter exit, how long live threads get to end

_lock = threading.Lock()
_live: set[WorkerThread] = set()  # started and not yet seen finished: never deleted meanwhile


class WorkerThread(QThread):
    """A QThread that runs `loop()` (a plain function that returns when its owner asks it to)
    and calls `request_stop()` to ask; see the module docstring for how it is kept alive.

    `loop` runs in the new thread; an exception ending it is logged, never raised into Qt.
    """

    def __init__(self, loop: Callable[[], None], name: str,
                 request_stop: Callable[[], None] | None = None, low_priority: bool = True) -> None:
        super().__init__()  # no parent: only this module decides when it may be deleted
        self.setObjectName(name)
        self._loop = loop
        self._request_stop = request_stop
        self._low_priority = low_priority
        self._given_up = False  # a join already waited its time in vain: later ones only look
        self.finished.connect(_reaper.reap)  # queued: the reaper lives in the main thread

    def start(self, *args: QThread.Priority) -> None:  # noqa: D102 - QThread.start, plus the bookkeeping
        with _lock:
            _live.add(self)
        super().start(*args)

    def run(self) -> None:  # runs in the new thread
        if self._low_priority:
            lower_thread_priority(WORKER_NICE)
        try:
            self._loop()
        except Exception:  # noqa: BLE001 - a loop's bug is logged, the process goes on
            log.exception("%s: its loop failed", self.objectName())

    def request_stop(self) -> None:
        """Ask the loop to end (returns at once)."""
        if self._request_stop is not None:
            self._request_stop()

    def join(self, timeout_ms: int) -> bool:
        """Wait at most `timeout_ms` for the thread to end; True if it has ended (or never
        started). A thread still running stays referenced here until it ends.

        A thread waited for in vain once is blocked: later joins return at once (closing the
        window and then leaving the application must not wait for it twice).
        """
        if not self.isRunning():
            _forget(self)
            return True
        if not self._given_up and self.wait(max(0, int(timeout_ms))):
            _forget(self)
            return True
        self._given_up = True
        return False


def _forget(t: WorkerThread) -> None:
    with _lock:
        _live.discard(t)


class _Reaper(QObject):
    """Drops a finished thread from `_live` in the main thread (dropping it in the thread's own
    `finished` could delete it from inside itself)."""

    @Slot()
    def reap(self) -> None:
        t = self.sender()
        if isinstance(t, WorkerThread) and t.wait(1000):  # it is ending: a moment at most
            _forget(t)


_reaper = _Reaper()  # created at import, in the importing (main) thread


def live_threads() -> list[WorkerThread]:
    """Worker threads started and not yet seen finished (running, or ended but not joined)."""
    with _lock:
        return sorted(_live, key=lambda t: t.objectName())


def _at_exit() -> None:
    threads = [t for t in live_threads() if t.isRunning()]
    if not threads:
        return
    for t in threads:
        try:
            t.request_stop()
        except Exception:  # noqa: BLE001 - exiting: one broken owner must not stop the others
            log.debug("asking %s to stop failed", t.objectName(), exc_info=True)
    deadline = time.monotonic() + EXIT_WAIT_MS / 1000.0
    stuck = [t for t in threads
             if not t.join(max(1, int((deadline - time.monotonic()) * 1000)))]
    if stuck:
        log.warning("exiting with %s still blocked (a device or OpenCV call that cannot be "
                    "interrupted); it ends with the process",
                    ", ".join(t.objectName() for t in stuck))
        keep_until_exit(stuck)


_keepers: list[QObject] = []


def keep_until_exit(threads: list[WorkerThread]) -> None:
    """Make running `threads` undeletable: PySide deletes at exit only what Python owns, so
    give them to C++ as children of two keepers that are each other's parent (a root nobody
    owns, deletes or reaches)."""
    if not _keepers:
        a, b = QObject(), QObject()
        a.setObjectName("thread-keeper")
        b.setObjectName("thread-keeper")
        b.setParent(a)
        a.setParent(b)
        _keepers.extend((a, b))
    for t in threads:
        t.setParent(_keepers[0])


atexit.register(_at_exit)
