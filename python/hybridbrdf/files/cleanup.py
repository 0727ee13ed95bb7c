"""What lets a writer clean up after itself: whether a writer's process is still alive (for the
temporaries of writers killed outright) and SIGTERM turned into an exception for the length of
a write."""

from __future__ import annotations

import contextlib
import os
import signal
import threading

from hybridbrdf.files.locks import _release_all_locks


def _pid_alive(pid: int) -> bool:
    """Whether a process ``pid`` exists on this machine (one we may not signal counts)."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    except (OverflowError, ValueError):  # not a pid this system can have
        return False
    return True


class _Terminated(BaseException):
    """SIGTERM arrived during an atomic write (BaseException: no ``except Exception`` keeps it)."""


@contextlib.contextmanager
def _sigterm_cleans_up():
    """Within the block, a SIGTERM raises :class:`_Terminated` so that ``except``/``finally``
    clauses run (the temporary is removed); on leaving, the signal is delivered again so the
    process still ends as SIGTERM ends it. Only where SIGTERM would kill outright (the default
    handler, main thread: Python runs signal handlers there); a program's own handler is left
    alone."""
    if (threading.current_thread() is not threading.main_thread()
            or signal.getsignal(signal.SIGTERM) is not signal.SIG_DFL):
        yield
        return
    received = []

    def handler(signum, frame):
        if not received:  # a second SIGTERM must not interrupt the cleanup of the first
            received.append(signum)
            raise _Terminated()

    try:
        signal.signal(signal.SIGTERM, handler)
        yield
    except _Terminated:
        pass
    finally:
        signal.signal(signal.SIGTERM, signal.SIG_DFL)
    if received:
        _release_all_locks()  # as the kernel would, but removing the lock files too
        signal.raise_signal(signal.SIGTERM)  # the default action: the process ends here
        raise KeyboardInterrupt("SIGTERM")  # reached only where the signal is blocked
