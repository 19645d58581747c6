"""Run the newest of a stream of requests on a background thread, so callbacks never wait for it.

A node that must answer its services within 100 ms hands slow work (planning a reference) to a
``LatestRequestWorker``: ``submit`` returns at once; a request submitted while an older one waits
replaces it; the result of a request that was superseded while it ran is dropped. ROS-free.
"""

from __future__ import annotations

import threading
from typing import Callable, Generic, TypeVar

Request = TypeVar('Request')
Result = TypeVar('Result')


class LatestRequestWorker(Generic[Request, Result]):
    """``build(request)`` on a daemon thread for the newest request; ``deliver(result)`` if still newest."""

    def __init__(self, build: Callable[[Request], Result], deliver: Callable[[Result], None],
                 on_error: Callable[[Exception], None], name: str = 'background') -> None:
        self._build, self._deliver, self._on_error = build, deliver, on_error
        self._condition = threading.Condition()
        self._pending: tuple[int, Request] | None = None
        self._submitted = 0
        self._finished = 0
        self._stopping = False
        self._thread = threading.Thread(target=self._loop, name=name, daemon=True)
        self._thread.start()

    def submit(self, request: Request) -> None:
        """Queue ``request`` in place of any request not yet started; never blocks on a build."""
        with self._condition:
            self._submitted += 1
            self._pending = (self._submitted, request)
            self._condition.notify()

    @property
    def busy(self) -> bool:
        """Whether a submitted request has not been finished (built and delivered, or dropped) yet."""
        with self._condition:
            return self._finished < self._submitted

    def wait_idle(self, timeout: float | None = None) -> bool:
        """Block until every submitted request is finished; False on timeout."""
        with self._condition:
            return self._condition.wait_for(lambda: self._finished >= self._submitted or self._stopping, timeout)

    def stop(self, timeout: float = 1.0) -> None:
        """End the thread after the build in progress, if any; pending requests are dropped."""
        with self._condition:
            self._stopping = True
            self._condition.notify_all()
        self._thread.join(timeout)

    def _loop(self) -> None:
        while True:
            with self._condition:
                self._condition.wait_for(lambda: self._pending is not None or self._stopping)
                if self._stopping:
                    return
                number, request = self._pending
                self._pending = None
            try:
                result = self._build(request)
                with self._condition:
                    current = number == self._submitted and not self._stopping
                if current:
                    self._deliver(result)
            except Exception as error:  # noqa: BLE001 - reported through on_error, the thread goes on
                self._on_error(error)
            with self._condition:
                self._finished = max(self._finished, number)
                self._condition.notify_all()
