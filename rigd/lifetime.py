"""Child processes that do not outlive their parent.

``rigd serve`` starts each calibration's worker as the leader of its own process group, and the worker's pool
processes join that group. Whoever ends a worker ends the group; a worker or pool process whose parent is gone
(killed with SIGKILL: nothing ran to stop it) notices and leaves, taking its group with it when it leads one.
"""

from __future__ import annotations

import os
import signal
import threading
import time

PARENT_POLL_S = 0.5  # how often a child looks whether its parent is still there


def leave(code: int) -> None:
    """Exit at once with ``code``; a process group leader (a calibration worker) ends its group first.

    SIGTERM, not SIGKILL: multiprocessing's resource tracker ignores it and removes the pool's semaphores once
    the others are gone; everything else in the group dies of it (this process included)."""
    if os.getpgrp() == os.getpid():
        os.killpg(os.getpid(), signal.SIGTERM)
    os._exit(code)


def exit_with_parent(parent_pid: int, code: int, poll_s: float = PARENT_POLL_S) -> threading.Thread:
    """A daemon thread that calls :func:`leave` with ``code`` when this process's parent is no longer
    ``parent_pid`` (an orphan is adopted by init or a subreaper). ``parent_pid`` is passed in rather than read
    here: the parent may already have died by the time the child runs this."""

    def watch() -> None:
        while os.getppid() == parent_pid:
            time.sleep(poll_s)
        leave(code)

    thread = threading.Thread(target=watch, name="rigd-parent-watch", daemon=True)
    thread.start()
    return thread
