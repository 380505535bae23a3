"""What the display draws of an engine session: one record — the newest snapshot with the newest prediction —
swapped in one step under the session's lock, a count of the records published so far, and a snapshot handed to
the engine held back for its prediction at most a wait (so that a slow engine never holds the cameras back).
Every method but `wait` expects the session's lock held; `wait` takes it."""
from __future__ import annotations

import threading
import time
from collections.abc import Callable


class PublishedRecord:
    def __init__(self, lock: threading.Lock) -> None:
        self._news = threading.Condition(lock)
        self.shown: tuple = (None, None)
        """The shown (snapshot, prediction record), as last published."""
        self.count = 0
        """Records published so far."""
        self._held_until: float | None = None
        """While a snapshot waits for its prediction: when it is published without one."""

    def hold(self, seconds: float) -> None:
        """A snapshot handed to the engine waits for its prediction, at most `seconds` after the first one held."""
        self._held_until = self._held_until or time.monotonic() + seconds

    def publish(self, record: tuple) -> None:
        """Make `record` the shown one, in one step, and wake every waiter."""
        self.shown = record
        self._held_until = None
        self.count += 1
        self._news.notify_all()

    def overdue(self) -> bool:
        """A held snapshot waited its time out (the session then publishes it without a prediction)."""
        return self._held_until is not None and time.monotonic() >= self._held_until

    def wait(self, seen: int, timeout: float, publish_overdue: Callable[[], None]) -> int:
        """Block until more than `seen` records were published or `timeout` s passed (calling `publish_overdue` so
        that a held snapshot is published when its wait is over); the number published now."""
        deadline = time.monotonic() + timeout
        with self._news:
            while self.count == seen:
                publish_overdue()
                now = time.monotonic()
                if self.count != seen or now >= deadline:
                    break
                self._news.wait(min(deadline, self._held_until or deadline) - now)
            return self.count
