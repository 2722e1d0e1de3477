"""What a tab offers the main window: being shown or hidden, and closing without losing work."""

from __future__ import annotations

from typing import Protocol, runtime_checkable


@runtime_checkable
class WindowTab(Protocol):
    """A page of the main window's tabs.

    The window calls `set_active` when the tab is shown or hidden (the shown tab owns the frame
    worker's processor). On close it asks every tab what closing now would cut short
    (`unfinished_work`, in words for a person), waits for that or has it cancelled
    (`cancel_unfinished_work`), then has each tab save what it keeps and stop its workers
    (`shutdown`), all within one deadline.
    """

    def set_active(self, active: bool) -> None: ...

    def unfinished_work(self) -> list[str]: ...

    def cancel_unfinished_work(self, timeout_ms: int) -> list[str]: ...

    def shutdown(self, timeout_ms: int) -> bool: ...
