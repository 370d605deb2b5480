"""Worker processes that end with the command that started them.

A SIGTERM (or SIGKILL) to `orthospec check` ended the command but left its pool's workers running as
orphans: in one run they kept a core busy for 35 minutes (issue 28). Every pool orthospec starts
takes its context and initializer from here: forkserver where the platform has it (workers fork from
a server that has imported the modules once; no inherited threads or GDAL handles), else spawn; and
each worker asks the kernel for SIGKILL when its parent ends (Linux ``PR_SET_PDEATHSIG``). The
forkserver asks the same when it starts (orthospec/_forkserver.py, preloaded), so the command's end,
whatever signal caused it, ends the server and the server's end ends every worker.
"""

from __future__ import annotations

import os
import signal
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any

_PR_SET_PDEATHSIG = 1


def mp_context(preload: Sequence[str] = ()) -> Any:
    """The multiprocessing context for orthospec's pools (forkserver preloading ``preload``, else spawn)."""
    import multiprocessing

    if "forkserver" in multiprocessing.get_all_start_methods():
        ctx = multiprocessing.get_context("forkserver")
        ctx.set_forkserver_preload(["orthospec._forkserver", *preload])
        return ctx
    return multiprocessing.get_context("spawn")


def die_with_parent(command: int | None = None) -> None:
    """Pool initializer: this worker is killed when its parent process ends (Linux; elsewhere a no-op).

    ``command`` is the pid of the command that made the pool (``initargs=(os.getpid(),)``): a command
    that ended before the request took effect (the worker's parent, the forkserver, may then be gone
    already, and the worker would belong to init) is seen after it, and the worker leaves at once.
    """
    if not sys.platform.startswith("linux"):
        return
    import ctypes

    parent = os.getppid()
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        libc.prctl(_PR_SET_PDEATHSIG, int(signal.SIGKILL), 0, 0, 0)
    except (OSError, AttributeError):  # pragma: no cover - a libc without prctl
        return
    if os.getppid() != parent or (command is not None and _ended(command)):
        os._exit(1)  # the command already ended: nobody will read this worker's results


def _ended(pid: int) -> bool:
    """The process is gone or a zombie (ended, not yet reaped by its own parent)."""
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return True
    return stat[stat.rindex(")") + 2 :].startswith("Z")
