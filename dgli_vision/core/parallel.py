"""Work spread over processes, results in input order: what ``-j N`` does for commands
whose items are independent (``render``, ``simulate``); and shared slots through which
large payloads reach worker processes without pickling (:class:`SharedSlots`).

Each item's result depends on the item alone (its own seed), so the results are those of
one process, in the same order, whatever the number of workers.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Iterator, Sequence
from dataclasses import dataclass
from typing import Any, TypeVar

from .errors import InvalidValueError

__all__ = [
    "ONE_THREAD_VARIABLES",
    "FileSpan",
    "SharedSlots",
    "SlotRef",
    "die_with_parent",
    "limit_library_threads",
    "ordered_map",
]

T = TypeVar("T")

#: The variables that keep OpenMP (Open3D's ray casting), OpenBLAS (numpy's matrix
#: products) and MKL to one thread; read once, when each library loads.
ONE_THREAD_VARIABLES = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")

#: ``prctl`` option: the signal a process gets when its parent exits (linux/prctl.h).
_PR_SET_PDEATHSIG = 1


def limit_library_threads(threads: int = 1) -> None:
    """Put ``threads`` threads per numerical library in the environment that worker
    processes started from now on inherit (:data:`ONE_THREAD_VARIABLES`; a value already
    set is kept). Called before a pool of ``spawn`` workers starts, with the cores per
    worker (one where there is one worker per core): a library starting a thread per
    core in each of several workers oversubscribes the cores (on two busy cores, a
    render's 921,600 x 3 matrix product took 10x the processor time with two OpenBLAS
    threads than with one). The variables must be there before a worker imports numpy,
    hence in the parent's environment, not in the initializer; OpenCV's pool, which can
    be set at any time, is set to one thread in the initializer. This process's
    libraries, already loaded, keep their threads.
    """
    import os

    for name in ONE_THREAD_VARIABLES:
        os.environ.setdefault(name, str(max(int(threads), 1)))


def die_with_parent() -> None:
    """A worker process's first act: end when the process that started it ends, however
    it ends (SIGKILL by the out-of-memory killer included), rather than live on holding
    its memory and waiting for work that never comes.

    Three ways, each enough alone: on Linux, ``prctl(PR_SET_PDEATHSIG)`` asks the kernel
    for SIGUSR2 when the parent goes, and its handler exits when the parent is gone
    (the kernel sends it when the parent *thread* that started the worker ends, which
    for a pool started from a helper thread is not the end of the process: hence the
    check, not SIGKILL); a daemon thread waits on the parent's end of the pipe
    ``multiprocessing`` keeps to each spawned child (it reads end-of-file when the
    parent is gone, on any system); and a parent already gone before these were set up
    is seen at once. Nothing in a process not started by ``multiprocessing``.
    """
    import multiprocessing
    import os
    import signal
    import threading

    parent = multiprocessing.parent_process()
    if parent is None:
        return
    parent_pid = parent.pid

    def parent_gone() -> bool:
        return os.getppid() != parent_pid

    def on_signal(signum: int, frame: Any) -> None:
        if parent_gone():
            os._exit(1)

    if hasattr(signal, "SIGUSR2") and threading.current_thread() is threading.main_thread():
        try:
            import ctypes

            libc = ctypes.CDLL(None, use_errno=True)
            signal.signal(signal.SIGUSR2, on_signal)
            signal.siginterrupt(signal.SIGUSR2, False)  # a false alarm interrupts no read
            libc.prctl(_PR_SET_PDEATHSIG, int(signal.SIGUSR2), 0, 0, 0)
        except (OSError, AttributeError, ValueError):
            pass  # not Linux: the thread below is enough
    sentinel = getattr(parent, "sentinel", None)
    if sentinel is not None:

        def watch() -> None:
            import time
            from multiprocessing.connection import wait

            wait([sentinel])  # end of file: the parent is gone (or closed it, alive)
            for _ in range(40):  # its files close before its children are handed on
                if parent_gone():
                    os._exit(1)
                time.sleep(0.05)

        threading.Thread(target=watch, name="dgli-parent-watch", daemon=True).start()
    if parent_gone():  # gone before any of this was set up
        os._exit(1)


def _quiet_worker() -> None:
    """Workers die with their parent (:func:`die_with_parent`), ignore Ctrl-C and run
    OpenCV on one thread: the parent stops the work (a terminal's interrupt reaches the
    whole process group) and there is one process per core."""
    import signal

    import cv2

    die_with_parent()
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    cv2.setNumThreads(1)


def ordered_map(func: Callable[[Any], T], items: Iterable[Any], *, jobs: int = 1) -> Iterator[T]:
    """``func`` of every item, in the order of ``items``, on ``jobs`` processes.

    Parameters
    ----------
    func : callable
        A module-level function (sent to spawned workers by name); its argument and
        result must pickle.
    items : iterable
    jobs : int, keyword-only
        Worker processes; 1 works in this process.

    Yields
    ------
    object
        ``func(item)``, as soon as it and every result before it are done. When the
        caller stops early (or Ctrl-C), the items not started are dropped and those
        running finish.
    """
    if jobs < 1:
        raise InvalidValueError(f"jobs must be at least 1, got {jobs}")
    if jobs == 1:
        for item in items:
            yield func(item)
        return
    import multiprocessing
    import os
    from concurrent.futures import ProcessPoolExecutor

    limit_library_threads(max(1, (os.cpu_count() or 1) // jobs))  # the cores per worker
    pool = ProcessPoolExecutor(
        jobs, mp_context=multiprocessing.get_context("spawn"), initializer=_quiet_worker
    )
    try:
        futures = [pool.submit(func, item) for item in items]
        for future in futures:
            yield future.result()
    finally:
        pool.shutdown(wait=True, cancel_futures=True)


@dataclass(frozen=True)
class SlotRef:
    """Bytes held in a slot of a :class:`SharedSlots` file: what a worker process is sent
    instead of the bytes themselves (a path and two numbers pickle in microseconds)."""

    path: str
    offset: int
    length: int

    def view(self) -> memoryview:
        """The bytes, read-only, without a copy (the file is mapped once per process)."""
        return _mapping(self.path)[self.offset : self.offset + self.length]


@dataclass(frozen=True)
class FileSpan:
    """Bytes that lie in a file as they are (a raw image in an uncompressed recording):
    what a worker process is sent instead of the bytes; it maps them itself."""

    path: str
    offset: int
    length: int

    def view(self) -> memoryview:
        """The bytes, read-only, without a copy: only their own pages are mapped, and
        unmapped once nothing refers to them.

        Raises
        ------
        OSError, ValueError
            The file cannot be opened, or is now shorter than the span.
        """
        import mmap

        if not self.length:
            return memoryview(b"")
        start = self.offset - self.offset % mmap.ALLOCATIONGRANULARITY
        with open(self.path, "rb") as f:
            size = self.offset + self.length - start
            mapped = mmap.mmap(f.fileno(), size, access=mmap.ACCESS_READ, offset=start)
        return memoryview(mapped)[self.offset - start :]


#: The slot file this process has mapped last, by path (kept: its slots are used over
#: and over; a mapping outlives the removal of its file, and is dropped for the next).
_MAPPED: dict[str, memoryview] = {}


def _mapping(path: str) -> memoryview:
    view = _MAPPED.get(path)
    if view is None:
        import mmap

        with open(path, "rb") as f:
            view = memoryview(mmap.mmap(f.fileno(), 0, access=mmap.ACCESS_READ))
        _MAPPED.clear()  # an earlier run's slots: unmapped once nothing reads them
        _MAPPED[path] = view
    return view


class SharedSlots:
    """Equal slots in one file of shared memory (``/dev/shm`` where there is one),
    through which a parent hands large byte payloads (a recording's raw images, 4.6 MB a
    1280 x 720 frame) to worker processes: one copy into the slot, no pickling and no
    pipe. The parent writes a slot (:meth:`put`), sends its :class:`SlotRef`, and frees
    the slot (:meth:`release`) once the worker's result is back; :meth:`close` removes
    the file. The file is made at the first :meth:`put`, its slots as large as that
    payload (a later, larger one does not fit: it is sent the usual way).

    Parameters
    ----------
    n_slots : int
        At most this many payloads in flight.
    """

    def __init__(self, n_slots: int) -> None:
        self.n_slots = n_slots
        self.path: str | None = None
        self.slot_bytes = 0
        self._map: Any = None
        self._free = list(range(n_slots - 1, -1, -1))

    def _open(self, slot_bytes: int) -> None:
        """Make the file, its space reserved: a shared memory too small for it (a
        container's 64 MB ``/dev/shm``) leaves the slots unused, rather than failing
        at the first write into a page it cannot hold."""
        import mmap
        import os
        import tempfile

        self.slot_bytes = -(-slot_bytes // mmap.PAGESIZE) * mmap.PAGESIZE
        size = self.n_slots * self.slot_bytes
        folder = "/dev/shm" if os.path.isdir("/dev/shm") else None
        try:
            fd, path = tempfile.mkstemp(prefix="dgli-slots-", dir=folder)
        except OSError:
            self._free = []
            return
        try:
            if hasattr(os, "posix_fallocate"):
                os.posix_fallocate(fd, 0, size)
            else:
                os.ftruncate(fd, size)
            self._map = mmap.mmap(fd, size)
            self.path = path
        except OSError:
            self._free = []  # no room: every payload goes the usual way
            os.unlink(path)
        finally:
            os.close(fd)

    def put(self, parts: Sequence[Any]) -> tuple[int, list[SlotRef]] | None:
        """Copy ``parts`` (bytes-like objects) into a free slot, one after the other:
        the slot and a reference to each part; None when no slot is free or they do
        not fit in one."""
        views = [memoryview(p).cast("B") for p in parts]
        need = sum(v.nbytes for v in views)
        if self._map is None and self._free and need:
            self._open(need)
        if self._map is None or not self._free or need > self.slot_bytes:
            return None
        slot = self._free.pop()
        offset, refs = slot * self.slot_bytes, []
        for v in views:
            self._map[offset : offset + v.nbytes] = v
            refs.append(SlotRef(self.path, offset, v.nbytes))
            offset += v.nbytes
        return slot, refs

    def release(self, slot: int) -> None:
        """Make ``slot`` free again (its worker is done with it, or never started)."""
        self._free.append(slot)

    def close(self) -> None:
        """Remove the file (mappings still open stay valid until they are closed)."""
        import os

        if self._map is None or self.path is None:
            return
        self._map.close()
        self._map = None
        try:
            os.unlink(self.path)
        except FileNotFoundError:
            pass
