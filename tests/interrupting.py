"""A timed wait interrupted by a signal while another thread holds the interpreter past its deadline:
what froze a ROS 2 robot process after Ctrl-C (CPython 3.11's SimpleQueue.get, transport/handoff.py).

Owns: staging that. Must not know: what waits.
"""

from __future__ import annotations

import random
import signal
import threading
import time
from collections.abc import Callable

#: Floats a thread sorts while holding the interpreter (sort never lets it go): about 0.3-1 s here.
HOG_ITEMS = 1_000_000


def interrupted_wait(wait: Callable[[], object], unblock: Callable[[], None], *, limit_s: float = 10.0):
    """Run `wait()` (a wait with a short timeout, well under the hog) on this thread, the main thread,
    while a helper sends this thread SIGUSR1 and then holds the interpreter for longer than the
    timeout. `unblock()` is called after `limit_s` s if the wait has not returned (it must end the
    wait: put an item). Returns (what wait returned or raised, seconds it took, whether unblock ran)."""
    assert threading.current_thread() is threading.main_thread(), "signals reach the main thread only"
    data = [random.random() for _ in range(HOG_ITEMS)]
    main = threading.get_ident()
    started = threading.Event()

    def hog() -> None:
        started.wait(5.0)
        time.sleep(0.01)  # the main thread is inside its wait by now
        signal.pthread_kill(main, signal.SIGUSR1)
        sorted(data)  # holds the interpreter until well past the wait's deadline

    unblocked = []
    watchdog = threading.Timer(limit_s, lambda: (unblocked.append(True), unblock()))
    previous = signal.signal(signal.SIGUSR1, lambda *_: None)
    helper = threading.Thread(target=hog, daemon=True)
    try:
        helper.start()
        watchdog.start()
        began = time.monotonic()
        started.set()
        try:
            outcome = wait()
        except Exception as exc:  # queue.Empty and the like: an outcome, not a failure of the staging
            outcome = exc
        took = time.monotonic() - began
    finally:
        watchdog.cancel()
        helper.join(10.0)
        signal.signal(signal.SIGUSR1, previous)
    return outcome, took, bool(unblocked)
