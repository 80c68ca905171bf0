"""A NodeODM processing node (or ClusterODM in front of many) through pyodm: the only module
that knows pyodm's API.

The task is the ODM project of :mod:`processing.handoff.odm` (images, geo.txt, gcp_list.txt,
the options): created with a UUID of our own (so a task whose upload failed can still be
removed), uploaded with pyodm's retries, followed to the end, and its results downloaded into
the project folder. Every failure is one :class:`~processing.handoff.errors.NodeError` whose
message says what to do; on any failure or Ctrl-C after the task exists, the task is cancelled
and removed from the node.

URLs: ``nodeodm://HOST:PORT`` (plain HTTP), ``http://HOST:PORT``, ``https://HOST`` (port 443:
pyodm speaks HTTPS on port 443 only).
"""

from __future__ import annotations

import contextlib
import logging
import threading
import time
import uuid
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any
from urllib.parse import urlparse

from .errors import HandoffInputError, NodeError

log = logging.getLogger(__name__)

#: Upload attempts per file before the upload is given up.
UPLOAD_RETRIES = 5
#: Seconds between task status requests.
POLL_INTERVAL_S = 2.0
#: Lines of the task's output quoted when it fails.
OUTPUT_TAIL_LINES = 20


@dataclass(frozen=True, kw_only=True)
class NodeAddress:
    host: str
    port: int
    https: bool

    @property
    def label(self) -> str:
        return f"{'https' if self.https else 'http'}://{self.host}:{self.port}"


def parse_node_url(url: str) -> NodeAddress:
    """``nodeodm://HOST:PORT``, ``http://HOST:PORT`` or ``https://HOST[:443]`` (an IPv6 host in
    brackets: ``nodeodm://[::1]:3000``). Anything else: one HandoffInputError naming the value and
    the fix."""
    try:
        u = urlparse(url)
        port = u.port
    except ValueError as error:  # "Port out of range", a port that is not a number, "Invalid IPv6 URL"
        raise HandoffInputError(
            f"{url!r} is not a node address ({error}); write nodeodm://HOST:PORT with PORT a number "
            "1-65535, an IPv6 host in brackets (nodeodm://[::1]:3000)"
        ) from None
    if u.scheme not in ("nodeodm", "http", "https") or not u.hostname:
        raise HandoffInputError(f"{url!r} is not a node address; write nodeodm://HOST:PORT or https://HOST")
    host = f"[{u.hostname}]" if ":" in u.hostname else u.hostname
    if u.scheme == "https":
        if port not in (None, 443):
            raise HandoffInputError(
                f"{url}: pyodm speaks HTTPS on port 443 only; put the node behind a proxy on 443"
            )
        return NodeAddress(host=host, port=443, https=True)
    if port is None:
        raise HandoffInputError(f"{url}: give the node's port, e.g. nodeodm://{host}:3000")
    if port == 0:
        raise HandoffInputError(
            f"{url}: port 0 is no port a node listens on; give its port (1-65535), e.g. 3000"
        )
    if port == 443:
        raise HandoffInputError(
            f"{url}: pyodm speaks HTTPS on port 443; write https://{host} for a node behind HTTPS there"
        )
    return NodeAddress(host=host, port=port, https=False)


@dataclass(frozen=True, kw_only=True)
class NodeRun:
    node: str
    task_uuid: str
    seconds: float
    results: tuple[str, ...]
    uploaded_files: int
    node_version: str

    def as_dict(self) -> dict[str, Any]:
        return {
            "node": self.node,
            "task_uuid": self.task_uuid,
            "seconds": self.seconds,
            "uploaded_files": self.uploaded_files,
            "results": list(self.results),
            "node_version": self.node_version,
        }


def _explain(error: Exception, address: NodeAddress, stage: str) -> NodeError:
    from pyodm.exceptions import NodeConnectionError, NodeResponseError, NodeServerError, TaskFailedError

    text = str(error)
    if isinstance(error, NodeConnectionError):
        return NodeError(
            f"cannot reach the node at {address.label} while {stage} "
            f"({text.splitlines()[0][:160]}); check that "
            "NodeODM runs there and the host and port are right"
        )
    if stage == "uploading":
        return NodeError(
            f"the upload to {address.label} failed after {UPLOAD_RETRIES} attempts per file "
            f"({text}); the task was "
            "removed from the node: check the connection and hand off again"
        )
    if isinstance(error, NodeResponseError) and ("token" in text.lower() or "unauthorized" in text.lower()):
        return NodeError(
            f"the node at {address.label} refused the token ({text}); pass the right one with --token"
        )
    if isinstance(error, NodeResponseError):
        return NodeError(f"the node at {address.label} refused the task while {stage}: {text}")
    if isinstance(error, NodeServerError):
        return NodeError(f"the node at {address.label} answered with an error while {stage}: {text}")
    if isinstance(error, TaskFailedError):
        return NodeError(f"the task failed on {address.label}: {text}")
    return NodeError(f"{stage} on {address.label} failed: {text}")


def _in_daemon_thread(work: Callable[[], Any], threads: list[threading.Thread] | None = None) -> Any:
    """Run ``work`` in a daemon thread and wait for it here. pyodm uploads and downloads with
    threads of its own that are not daemons; started from a daemon thread they are daemons too,
    so Ctrl-C (which arrives here, in the main thread) cannot leave the process hanging on them.
    The thread is appended to ``threads`` (so a clean-up can wait for it)."""
    outcome: dict[str, Any] = {}

    def run() -> None:
        try:
            outcome["value"] = work()
        except BaseException as error:
            outcome["error"] = error

    thread = threading.Thread(target=run, daemon=True, name="nodeodm-transfer")
    if threads is not None:
        threads.append(thread)
    thread.start()
    while thread.is_alive():
        thread.join(0.2)
    if "error" in outcome:
        raise outcome["error"]
    return outcome.get("value")


class _UploadStoppedError(Exception):
    """Raised in pyodm's upload workers once the upload is given up (failure or Ctrl-C)."""


#: Seconds the clean-up waits for uploads already on the wire before it clears the node's upload.
UPLOAD_STOP_WAIT_S = 12.0


def _clear_upload(
    node: Any, task: Any, task_uuid: str, address: NodeAddress, transfers: list[threading.Thread]
) -> str:
    """Remove what an unfinished task left on the node; returns what remains there, in words.

    NodeODM's API has no call that deletes an upload in progress (its files wait in the node's
    tmp/<uuid> until --cleanup_uploads_after, 2880 minutes by default). What it allows: commit the
    upload, which moves the files into a task (or, with no file, deletes the folder), then cancel
    and remove that task, which deletes its folder. A file still on the wire after
    :data:`UPLOAD_STOP_WAIT_S` can land after the commit and stay in tmp/<uuid>."""
    from pyodm.exceptions import OdmError

    deadline = time.monotonic() + UPLOAD_STOP_WAIT_S
    for thread in transfers:
        thread.join(max(0.0, deadline - time.monotonic()))
    in_flight = any(t.is_alive() for t in transfers)
    committed = False
    with contextlib.suppress(OdmError, OSError):
        answer = node.post(f"/task/new/commit/{task_uuid}")
        committed = isinstance(answer, dict) and "error" not in answer
    with contextlib.suppress(OdmError, OSError):
        task.cancel()
    with contextlib.suppress(OdmError, OSError):
        task.remove()
    remains = (
        f"uploads still in progress when it was cleared may leave files in the node's tmp/{task_uuid} until "
        "its clean-up (NodeODM --cleanup_uploads_after, 2880 minutes by default)"
        if in_flight
        else "nothing"
    )
    log.warning(
        "task %s: %s and removed from %s; left on the node: %s",
        task_uuid,
        "the partial upload was committed, cancelled" if committed else "cancelled",
        address.label,
        remains,
    )
    return remains


def check_options(available: Sequence[str], options: Sequence[dict[str, Any]], address: NodeAddress) -> None:
    unknown = [o["name"] for o in options if o["name"] not in available]
    if unknown:
        raise NodeError(
            f"the node at {address.label} does not take the option(s) {', '.join(unknown)} (it is "
            "older or not "
            "ODM); update NodeODM or hand off with --to odm and set the options by hand"
        )


def run_on_node(
    address: NodeAddress,
    *,
    token: str,
    files: Sequence[Path],
    options: Sequence[dict[str, Any]],
    name: str,
    results_dir: Path,
    progress: Callable[[str], None] | None = None,
    timeout_s: float = 30.0,
    poll_interval_s: float = POLL_INTERVAL_S,
) -> NodeRun:
    """Create, upload, follow and download a task on the node; clean up on failure (module doc)."""
    from pyodm import Node
    from pyodm.exceptions import OdmError, TaskFailedError

    say = progress or (lambda text: None)
    node = Node(address.host, address.port, token=token, timeout=timeout_s)
    try:
        info = node.info()
        available = [o.name for o in node.options()]
    except OdmError as error:
        raise _explain(error, address, "asking for its information") from None
    check_options(available, options, address)
    say(f"node {address.label}: NodeODM {info.version}, engine {info.engine} {info.engine_version}")
    # pyodm's create_task does init, uploads and commit in one call: note which request failed.
    phase = ["creating the task"]
    plain_post = node.post

    def post(url: str, *args: Any, **kwargs: Any) -> Any:
        if url.startswith("/task/new/upload"):
            phase[0] = "uploading"
        elif url.startswith("/task/new/commit"):
            phase[0] = "committing the upload"
        return plain_post(url, *args, **kwargs)

    stop = threading.Event()
    transfers: list[threading.Thread] = []

    def guarded_post(url: str, *args: Any, **kwargs: Any) -> Any:
        if stop.is_set() and url.startswith("/task/new/upload"):
            raise _UploadStoppedError("the upload was given up")
        return post(url, *args, **kwargs)

    node.post = guarded_post
    task_uuid = str(uuid.uuid4())
    task = node.get_task(task_uuid)
    created = False
    start = time.perf_counter()
    last = [-1]

    def upload_progress(pct: float) -> None:
        step = int(pct // 10) * 10
        if step > last[0]:
            last[0] = step
            say(f"upload: {pct:.0f}% of {len(files)} files")

    try:
        created = True  # from here a partial task may exist on the node
        _in_daemon_thread(
            lambda: node.create_task(
                [str(f) for f in files],
                {o["name"]: o["value"] for o in options},
                name=name,
                progress_callback=upload_progress,
                max_retries=UPLOAD_RETRIES,
                retry_timeout=1,
                parallel_uploads=4,
                task_uuid=task_uuid,
            ),
            transfers,
        )
        phase[0] = "processing"
        state = {"progress": -1.0}

        def status(ti: Any) -> None:
            if ti.progress - state["progress"] >= 5 or ti.status.name != "RUNNING":
                state["progress"] = ti.progress
                say(f"task {ti.status.name.lower()}: {ti.progress:.0f}%")

        try:
            task.wait_for_completion(status_callback=status, interval=poll_interval_s)
        except TaskFailedError:
            tail: list[str] = []
            with contextlib.suppress(OdmError):
                tail = list(task.output(-OUTPUT_TAIL_LINES))
            last_error = ""
            with contextlib.suppress(OdmError):
                last_error = task.info().last_error
            raise NodeError(
                f"the task failed on {address.label}"
                + (f": {last_error}" if last_error else "")
                + (". Last lines of its output:\n  " + "\n  ".join(tail) if tail else "")
                + "\nFix the cause (the output says what) and hand off again"
            ) from None
        phase[0] = "downloading the results"
        say("download: results")
        results_dir.mkdir(parents=True, exist_ok=True)
        _in_daemon_thread(lambda: task.download_assets(str(results_dir)))
        results = tuple(
            sorted(str(p.relative_to(results_dir)) for p in results_dir.rglob("*") if p.is_file())
        )
        with contextlib.suppress(OdmError):
            task.remove()
        created = False
        return NodeRun(
            node=address.label,
            task_uuid=task_uuid,
            seconds=time.perf_counter() - start,
            results=results,
            uploaded_files=len(files),
            node_version=str(info.version),
        )
    except OdmError as error:
        raise _explain(error, address, phase[0]) from None
    finally:
        if created:
            # Failure or Ctrl-C: the node keeps nothing of ours that its API lets us remove.
            stop.set()
            if phase[0] in ("creating the task", "uploading", "committing the upload"):
                node.post = post  # the clean-up's own requests pass
                _clear_upload(node, task, task_uuid, address, transfers)
            else:
                with contextlib.suppress(OdmError, OSError):
                    task.cancel()
                with contextlib.suppress(OdmError, OSError):
                    task.remove()
                log.info("task %s cancelled and removed from %s", task_uuid, address.label)
