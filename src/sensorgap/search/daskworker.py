"""Start-up of each worker process of sensorgap's local Dask cluster (``DaskExecutor``),
a Dask preload module (``distributed``'s ``preload``: ``dask_setup`` runs in the worker
process as the worker starts).

The cluster's processes are started with the stop signals blocked
(``runtime.children_spared_stop_signals``), so a signal to the command's process group (a
terminal's Ctrl-C, a closed terminal's SIGHUP, ``timeout``) did not reach them while they
started. Here a worker leaves that process group for one of its own, where such signals
never reach it, and unblocks them, so its nanny can still stop it with SIGTERM: the
command, stopping, closes the cluster itself (hostile round twenty, F3: the workers died
of the group's signal, their nannies restarted them, and warnings and tracebacks filled
standard error)."""

from __future__ import annotations

import logging
import os
import signal


def dask_setup(worker: object) -> None:
    """Dask's preload hook: this worker process into a process group of its own, then
    its stop signals unblocked (see the module docstring), and its log silenced: a task
    that fails reaches the command as an error of its own, and a worker outliving the
    stopped command by a moment logged its lost scheduler with two tracebacks on the
    command's standard error (hostile round twenty-one). ``worker``: the Dask worker
    (unused)."""
    for name in ("distributed", "tornado", "asyncio"):
        logging.getLogger(name).setLevel(logging.CRITICAL + 1)
    try:
        os.setpgid(0, 0)
    except OSError:  # already a group leader, or not permitted: signals stay as they are
        return
    if hasattr(signal, "pthread_sigmask"):
        stops = [getattr(signal, n) for n in ("SIGINT", "SIGTERM", "SIGHUP") if hasattr(signal, n)]
        if hasattr(signal, "sigtimedwait"):
            # a signal the group got while this process started is pending: dropped, it
            # was the command's to take
            while signal.sigtimedwait(stops, 0) is not None:
                pass
        signal.pthread_sigmask(signal.SIG_UNBLOCK, stops)
