"""One piece of work done aside, on the machine's other core, while this process goes on.

``sfap plan`` spends a third of a small plan drawing and encoding map.png, work that needs only
the plan and ends in its own file. :func:`start_aside` runs such a job in a child forked from
this process (it inherits the plan, the imports and the staging folder at no cost: the pages are
shared until written) while the parent writes the other files; :meth:`Aside.wait` waits for its
word and raises the child's error, if any, in the parent, as if the job had run there (a child
that says its job is done is reaped once it has exited, without waiting for the kernel to take
down its memory: :func:`reap_exited`). A thread would not
do: drawing and encoding hold the interpreter lock (tried: no gain, BENCHMARKS.md).

The child is forked only where that is safe and useful: on a POSIX system, in a process with one
thread (a fork copies only the forking thread: a lock another thread held would stay locked in
the child), on a machine with more than one core. Anywhere else the job runs in this process,
at once, with the same result. The output is the job's own: the child shares nothing back but
its error (pickled through a pipe) or its success.

:class:`Helper` is a child started earlier, before the job exists: a fresh interpreter (posix_spawn,
not a fork) that imports and loads what the job will need (``warm``, named: Pillow, its PNG
writer and the map's fonts, 25-30 ms of a small plan) while this process is still planning, then
waits for the job (a module-level function and its arguments, pickled through a pipe: a small
plan in about a millisecond) and runs it at once. While it waits it faults in the memory the job
will use (``room_bytes``: the map's canvases, 30-40 MB), a few MiB at a time, and stops as soon as the
job comes. Spawned rather than forked for two reasons:

- glibc reads its tunables only when a process starts, and the helper is started asking malloc to
  serve allocations up to 32 MiB from its heap and to keep what is freed
  (``glibc.malloc.mmap_threshold``, ``glibc.malloc.trim_threshold``): the memory faulted in
  while waiting, freed, is what the job's allocations get, and one canvas's memory is the next
  one's. A first touch of memory costs about 1 ms a MB on a virtual machine whose host takes back
  the pages its guest frees (free page reporting); the map's body took 8,000 page faults and
  12-29 ms of system time in its 40-55 ms, none with the room (BENCHMARKS.md). An earlier helper
  asked for transparent huge pages instead (``glibc.malloc.hugetlb=1``): fewer faults on a quiet
  host, but on such a guest every huge page is memory the host took back, and half the maps took
  90-200 ms of system time.
- a spawned child shares no page with this one, and is safe with other threads running.
"""

from __future__ import annotations

import atexit
import contextlib
import importlib
import logging
import os
import pickle
import signal
import sys
import typing
from collections.abc import Callable
from typing import NoReturn

log = logging.getLogger(__name__)


def can_fork() -> bool:
    """True when a child forked now would be safe and could run beside this process: fork exists,
    this process has one thread (Python's or a library's: /proc/self/task) and the machine more
    than one core available to it."""
    if not hasattr(os, "fork") or not hasattr(os, "sched_getaffinity"):
        return False
    try:
        if len(os.sched_getaffinity(0)) < 2 or len(os.listdir("/proc/self/task")) != 1:
            return False
    except OSError:
        return False
    return True


class Aside:
    """A job started by :func:`start_aside`: running in a child process (``pid``), or already done
    in this one (``pid`` None; ``error`` what it raised)."""

    def __init__(self, what: str, pid: int | None, read_fd: int | None, error: BaseException | None) -> None:
        self.what = what
        self.pid = pid
        self._read_fd = read_fd
        self._error = error
        self._send_fd: int | None = None  # a started job's pipe (Helper.start)
        self._unsent: tuple[Callable[..., object], tuple[object, ...]] | None = None  # not begun yet

    def send(self, value: object) -> None:
        """Give a job begun by :meth:`Helper.start` the value its ``receive()`` returns (once).
        A job the helper could not take begins now (:func:`start_aside`)."""
        if self._send_fd is not None:
            fd, self._send_fd = self._send_fd, None
            try:
                _write_message(fd, value)
            except OSError as error:  # the helper is gone: wait() says why
                log.debug("%s: the helper took no more (%s)", self.what, error)
            finally:
                os.close(fd)
        elif self._unsent is not None:
            (job, args), self._unsent = self._unsent, None
            begun = start_aside(lambda: job(*args, lambda: value), self.what)
            self.pid, self._read_fd, self._error = begun.pid, begun._read_fd, begun._error
        else:
            raise RuntimeError(f"{self.what}: nothing waits for a value")

    @property
    def forked(self) -> bool:
        """True when the job runs (or ran) in a child process."""
        return self.pid is not None

    def wait(self) -> None:
        """Wait for the job to end; raise what it raised (in the child: the same exception,
        unpickled; a child killed by a signal: an OSError naming the job and the signal). A child
        that reported its job done is not waited for to exit (:func:`reap_exited`)."""
        if self._send_fd is not None or self._unsent is not None:
            self.cancel()
            raise RuntimeError(f"{self.what}: waited on before it was sent its value (Aside.send)")
        if self.pid is None:
            error, self._error = self._error, None
            if error is not None:
                raise error
            return
        assert self._read_fd is not None
        with os.fdopen(self._read_fd, "rb") as pipe:
            self._read_fd = None
            report = pipe.read()
        if report == _DONE:  # its job is done: its exit is not waited for (reap_exited)
            _exiting.add(self.pid)
            self.pid = None
            reap_exited()
            return
        _, status = os.waitpid(self.pid, 0)
        self.pid = None
        if report:
            raise _unpickled(report, self.what)
        if os.WIFSIGNALED(status):
            number = os.WTERMSIG(status)
            raise OSError(f"{self.what}: the process writing it was ended by signal {number}")
        code = os.waitstatus_to_exitcode(status)
        if code != 0:
            raise OSError(f"{self.what}: the process writing it failed (exit code {code})")

    def cancel(self) -> None:
        """Stop the job if it still runs (the caller failed: its result is not wanted)."""
        self._unsent = None
        if self._send_fd is not None:
            os.close(self._send_fd)
            self._send_fd = None
        if self.pid is not None:
            with contextlib.suppress(ProcessLookupError):
                os.kill(self.pid, signal.SIGKILL)
            os.waitpid(self.pid, 0)
            self.pid = None
        if self._read_fd is not None:
            os.close(self._read_fd)
            self._read_fd = None
        self._error = None


def _unpickled(report: bytes, what: str) -> BaseException:
    try:
        error = pickle.loads(report)
    except Exception:  # an exception pickle cannot rebuild: its text
        return OSError(f"{what}: {report.decode(errors='replace')}")
    return error if isinstance(error, BaseException) else OSError(f"{what}: {error}")


def start_aside(job: Callable[[], object], what: str) -> Aside:
    """Start ``job()`` in a child process when :func:`can_fork`, else run it here at once.

    ``what`` names the job in errors (the file it writes). The job must not need to tell this
    process anything but that it failed: what it returns is dropped. Call :meth:`Aside.wait`
    (or :meth:`Aside.cancel` on a failure of the caller) before using its result."""
    if not can_fork():
        try:
            job()
        except Exception as error:
            return Aside(what, None, None, error)
        return Aside(what, None, None, None)
    _flush_std()
    read_fd, write_fd = os.pipe()
    pid = os.fork()
    if pid == 0:
        os.close(read_fd)
        _report_and_exit(write_fd, job)
    os.close(write_fd)
    log.debug("%s: drawn aside by process %d", what, pid)
    return Aside(what, pid, read_fd, None)


#: A child's report of a job done (a pickle, or an error's text, is never this byte alone).
_DONE = b"\x00"


def _report_and_exit(write_fd: int, run: Callable[[], object]) -> NoReturn:
    """In a child: ``run()``, its error pickled into ``write_fd`` (or :data:`_DONE`), then out
    without cleaning up (no atexit handlers, no flush of the parent's buffers, no finally block of
    the parent's). The report's pipe and the standard streams are closed before the exit: the
    parent, and whoever reads this process's output, need not wait for the kernel to take down
    its memory (some milliseconds for the map's 90 MB)."""
    status = 0
    try:
        try:
            run()
        except BaseException as error:  # every failure goes to the parent
            status = 1
            try:
                report = pickle.dumps(error)
            except Exception:
                report = f"{type(error).__name__}: {error}".encode()
            _write_all(write_fd, report)  # the parent reads it all when it waits
        else:
            _write_all(write_fd, _DONE)
        for fd in (write_fd, 0, 1, 2):
            with contextlib.suppress(OSError):
                os.close(fd)
    finally:
        os._exit(status)


#: Children whose job is done (their report said so) and that may still be exiting.
_exiting: set[int] = set()


def reap_exited(*, block: bool = False) -> None:
    """Reap the children whose job was done (:meth:`Aside.wait` does not wait for their exit):
    those that have exited, or (``block``) all of them. Done at each wait and at this process's
    normal exit; a process that ends with ``os._exit`` leaves them to the system."""
    for pid in list(_exiting):
        try:
            reaped, _ = os.waitpid(pid, 0 if block else os.WNOHANG)
        except ChildProcessError:  # reaped elsewhere
            reaped = pid
        if reaped:
            _exiting.discard(pid)


atexit.register(reap_exited, block=True)


#: Asked of glibc in the helper (see the module's text): allocations up to 32 MiB (glibc's
#: largest threshold) from the heap, and what is freed kept there up to 256 MiB.
KEEP_MEMORY_TUNABLES = {"glibc.malloc.mmap_threshold": "33554432", "glibc.malloc.trim_threshold": "268435456"}

#: The helper's program: the parent's import path, then serve (the arguments: the job's pipe, the
#: report's pipe, the warm-up's name, the room's bytes, then the path).
_HELPER_CODE = (
    "import sys; sys.path[:] = sys.argv[5:]; from planner.aside import _serve_spawned; "
    "_serve_spawned(int(sys.argv[1]), int(sys.argv[2]), sys.argv[3], int(sys.argv[4]))"
)


def can_spawn() -> bool:
    """True when a helper interpreter can be started beside this one and run on its own core:
    posix_spawn exists, this interpreter's path is known and is Python's own (not a frozen
    application's, which would read ``-c`` as its own option), and more than one core is
    available."""
    if not hasattr(os, "posix_spawn") or not sys.executable or getattr(sys, "frozen", False):
        return False
    try:
        cores = len(os.sched_getaffinity(0))
    except (AttributeError, OSError):
        cores = os.cpu_count() or 1
    return cores >= 2


def helper_environment() -> dict[str, str]:
    """The helper's environment: this one's, with malloc asked to keep its memory
    (:data:`KEEP_MEMORY_TUNABLES`, GLIBC_TUNABLES) where the user's own tunables do not say."""
    env = dict(os.environ)
    tunables = [t for t in env.get("GLIBC_TUNABLES", "").split(":") if t]
    named = {t.split("=", 1)[0] for t in tunables}
    tunables += [f"{name}={value}" for name, value in KEEP_MEMORY_TUNABLES.items() if name not in named]
    env["GLIBC_TUNABLES"] = ":".join(tunables)
    return env


class Helper:
    """A child interpreter started now (:func:`can_spawn`) that runs ``warm`` at once (a function
    named ``"module:function"``), faults in up to ``room_bytes`` bytes of memory for the job while it
    waits for it (glibc only: elsewhere malloc would give the memory back), then runs one job
    sent later by :meth:`submit`; where none can be started, nothing is, and the job runs when
    submitted (:func:`start_aside`). :meth:`close` when no job will come (always safe)."""

    def __init__(self, warm: str | None = None, room_bytes: int = 0) -> None:
        self.pid: int | None = None
        self._job_fd: int | None = None
        self._report_fd: int | None = None
        if not can_spawn():
            return
        _flush_std()
        job_read, job_write = os.pipe()
        report_read, report_write = os.pipe()
        _widen(job_write)
        ends = [str(job_read), str(report_write)]
        argv = [sys.executable, "-c", _HELPER_CODE, *ends, warm or "", str(room_bytes), *sys.path]
        try:
            os.set_inheritable(job_read, True)  # the child's two ends, and only those
            os.set_inheritable(report_write, True)
            pid = os.posix_spawn(sys.executable, argv, helper_environment())
        except OSError as error:
            log.debug("no helper process (%s): the job will run when sent", error)
            os.close(job_write)
            os.close(report_read)
            return
        finally:
            os.close(job_read)
            os.close(report_write)
        self.pid, self._job_fd, self._report_fd = pid, job_write, report_read

    def submit(self, job: Callable[..., object], *args: object, what: str) -> Aside:
        """``job(*args)`` in the helper (``job`` a module-level function of an importable module:
        it is pickled by name; the arguments by value); otherwise, or when no helper runs or the
        arguments cannot be pickled, by :func:`start_aside`. ``what`` names the job in errors.
        Wait on the :class:`Aside` returned."""
        aside = self._send(job, args, what, more=False)
        return aside if aside is not None else start_aside(lambda: job(*args), what)

    def start(self, job: Callable[..., object], *args: object, what: str) -> Aside:
        """``job(*args, receive)`` begun in the helper now: ``receive()`` there returns the value
        given later to :meth:`Aside.send` (the job's first part runs meanwhile). Where
        :meth:`submit` would not send the job to the helper, it begins at :meth:`Aside.send`, by
        :func:`start_aside`. Send, then wait on the :class:`Aside` returned (or cancel it)."""
        aside = self._send(job, args, what, more=True)
        if aside is None:
            aside = Aside(what, None, None, None)
            aside._unsent = (job, args)
        return aside

    def _send(
        self, job: Callable[..., object], args: tuple[object, ...], what: str, *, more: bool
    ) -> Aside | None:
        """The job sent to the helper (``more``: its pipe left open for :meth:`Aside.send`), or
        None, the helper stopped, when it cannot be (no helper, or it cannot import the job or
        take the arguments)."""
        data = None
        if self.pid is not None and _importable(job):
            try:
                data = pickle.dumps((job, args, more), protocol=pickle.HIGHEST_PROTOCOL)
            except Exception as error:  # an argument pickle cannot take: run here
                log.debug("%s: not sent aside (%s)", what, error)
        if data is None:
            self.close()
            return None
        assert self._job_fd is not None and self.pid is not None
        try:
            _write_all(self._job_fd, len(data).to_bytes(_LENGTH, "little") + data)
        except OSError as error:  # the helper is gone (it died warming up): do without it
            log.debug("%s: no helper to take it (%s)", what, error)
            self.close()
            return None
        job_fd, self._job_fd = self._job_fd, None
        aside = Aside(what, self.pid, self._report_fd, None)
        self.pid = self._report_fd = None
        if more:
            aside._send_fd = job_fd
        else:
            os.close(job_fd)  # closed: the job is whole
        log.debug("%s: drawn aside by process %d", what, aside.pid)
        return aside

    def close(self) -> None:
        """No job will come (the caller failed, or will do without): the helper, which has
        written nothing, is stopped at once. A job already submitted goes on (wait on it)."""
        if self.pid is None:
            return
        with contextlib.suppress(ProcessLookupError):
            os.kill(self.pid, signal.SIGKILL)
        os.waitpid(self.pid, 0)
        self.pid = None
        for fd in (self._job_fd, self._report_fd):
            if fd is not None:
                os.close(fd)
        self._job_fd = self._report_fd = None

    def __enter__(self) -> Helper:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def _importable(job: Callable[..., object]) -> bool:
    """True when another interpreter can import ``job`` by its name."""
    module, name = getattr(job, "__module__", None), getattr(job, "__qualname__", "<")
    return module not in (None, "__main__") and "<" not in name and "." not in name


def _serve_spawned(job_fd: int, report_fd: int, warm: str, room_bytes: int) -> NoReturn:
    """The helper interpreter's program (_HELPER_CODE)."""
    _report_and_exit(report_fd, lambda: _serve(job_fd, warm, room_bytes))


def _serve(job_fd: int, warm: str, room_bytes: int) -> None:
    """The helper's life: warm up, fault in its room until the job comes, read one job (nothing:
    leave), run it (with ``receive`` when it was started: Helper.start)."""
    if warm:
        with contextlib.suppress(Exception):  # only a head start: the job says what fails
            module, name = warm.split(":")
            getattr(importlib.import_module(module), name)()
    if room_bytes > 0 and _glibc():
        _fault_in(room_bytes, job_fd)
    with os.fdopen(job_fd, "rb") as pipe:
        try:
            job, args, more = _read_message(pipe)
        except EOFError:  # no job came
            return
        if more:
            job(*args, lambda: _read_message(pipe))
        else:
            job(*args)


def _glibc() -> bool:
    """True when this process's C library is glibc (which reads KEEP_MEMORY_TUNABLES)."""
    try:
        return os.confstr("CS_GNU_LIBC_VERSION") is not None
    except (AttributeError, ValueError, OSError):
        return False


#: The room is faulted in this many bytes at a time, the job's pipe looked at between them.
_ROOM_STEP_BYTES = 4 << 20


def _fault_in(room_bytes: int, job_fd: int) -> None:
    """Touch every page of up to ``room_bytes`` of new memory, :data:`_ROOM_STEP_BYTES` at a time,
    until all is touched or something can be read from ``job_fd`` (the job, or the end of the
    pipe), then free it: malloc keeps it (KEEP_MEMORY_TUNABLES) for the job's allocations."""
    import select

    page = os.sysconf("SC_PAGESIZE")
    poller = select.poll()
    poller.register(job_fd, select.POLLIN)
    steps: list[bytearray] = []
    while len(steps) * _ROOM_STEP_BYTES < room_bytes and not poller.poll(0):
        step = bytearray(_ROOM_STEP_BYTES)  # calloc: fresh memory is not written to yet
        step[::page] = bytes(len(range(0, _ROOM_STEP_BYTES, page)))
        steps.append(step)
    del steps


def _widen(fd: int) -> None:
    """The pipe of ``fd`` made to hold the map's job of a plan of several thousand stations whole
    (Linux; elsewhere, or when refused, it stays as it is): the parent then does not wait for the
    helper, still warming up, to read its job."""
    with contextlib.suppress(AttributeError, OSError):
        import fcntl

        fcntl.fcntl(fd, fcntl.F_SETPIPE_SZ, _PIPE_BYTES)


#: The job pipe's size asked for: Linux's limit for a user's pipes (fs.pipe-max-size) by default.
_PIPE_BYTES = 1 << 20

#: Bytes of a message's length, ahead of its pickle, on the helper's job pipe.
_LENGTH = 8


def _write_all(fd: int, data: bytes) -> None:
    view = memoryview(data)
    while view:
        view = view[os.write(fd, view) :]


def _write_message(fd: int, value: object) -> None:
    data = pickle.dumps(value, protocol=pickle.HIGHEST_PROTOCOL)
    _write_all(fd, len(data).to_bytes(_LENGTH, "little") + data)


def _read_message(pipe: typing.BinaryIO) -> typing.Any:
    """The next value sent on the pipe (:func:`_write_message`); EOFError when the sender closed
    it first."""
    head = pipe.read(_LENGTH)
    if len(head) < _LENGTH:
        raise EOFError("the pipe was closed before a message")
    size = int.from_bytes(head, "little")
    data = pipe.read(size)
    if len(data) < size:
        raise EOFError("the pipe was closed within a message")
    return pickle.loads(data)


def _flush_std() -> None:
    for stream in (sys.stdout, sys.stderr):  # nothing buffered written twice
        with contextlib.suppress(AttributeError, OSError, ValueError):
            stream.flush()
