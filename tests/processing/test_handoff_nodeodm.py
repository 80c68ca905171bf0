"""NodeODM hand-off: what can be tested offline (addresses, an unreachable node, a node that refuses
the token, the options or the task, served by a small HTTP peer on 127.0.0.1 that answers as
NodeODM's API does), and the whole life cycle against a real NodeODM when SFAP_NODEODM_URL is set
(e.g. `node index.js --test --port 3001`; also with --test_drop_uploads and --test_fail_tasks)."""

from __future__ import annotations

import json
import os
import re
import signal
import socket
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path
from typing import Any
from urllib.parse import urlparse

import numpy as np
import pytest
from handoff_grid import grid

from processing.handoff.errors import HandoffInputError, NodeError
from processing.handoff.nodeodm import NodeAddress, parse_node_url, run_on_node
from processing.handoff.pipeline import Engine, HandoffOptions, handoff
from processing.handoff.prepare import GroundOptions

OUR_OPTIONS = ["camera-lens", "gps-accuracy", "matcher-neighbors"]


def test_node_addresses() -> None:
    assert parse_node_url("nodeodm://10.0.0.5:3000") == NodeAddress(host="10.0.0.5", port=3000, https=False)
    assert parse_node_url("https://odm.example.org") == NodeAddress(
        host="odm.example.org", port=443, https=True
    )
    assert parse_node_url("nodeodm://[::1]:3000") == NodeAddress(host="[::1]", port=3000, https=False)
    for bad in ("nodeodm://host", "ftp://host:21", "https://host:8443"):
        with pytest.raises(HandoffInputError):
            parse_node_url(bad)


@pytest.mark.parametrize(
    ("url", "says"),
    [
        ("nodeodm://127.0.0.1:notaport", "Port could not be cast"),
        ("nodeodm://127.0.0.1:99999", "out of range"),
        ("nodeodm://[::1", "Invalid IPv6 URL"),
        ("nodeodm://127.0.0.1:0", "port 0 is no port"),
        ("nodeodm://127.0.0.1:443", "https://127.0.0.1"),
    ],
)
def test_a_bad_node_address_is_one_line_and_exit_2_before_any_work(
    tmp_path: Path, url: str, says: str
) -> None:
    from click.testing import CliRunner

    from sfap.cli import cli

    grid(tmp_path / "img", lines=1, per_line=2, dx_m=110.0, dy_m=45.0)
    result = CliRunner().invoke(
        cli, ["handoff", str(tmp_path / "img"), "--to", url, "-o", str(tmp_path / "w")]
    )
    assert result.exit_code == 2, result.output
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and says in lines[0] and url in lines[0], result.stderr
    assert "Traceback" not in result.output and not (tmp_path / "w").exists()


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def test_an_unreachable_node_is_named(tmp_path: Path) -> None:
    port = _free_port()
    with pytest.raises(NodeError, match=rf"cannot reach the node at http://127.0.0.1:{port}"):
        run_on_node(
            NodeAddress(host="127.0.0.1", port=port, https=False),
            token="",
            files=[],
            options=[],
            name="t",
            results_dir=tmp_path / "r",
            timeout_s=2.0,
        )


class _Peer(BaseHTTPRequestHandler):
    """Answers as NodeODM 2.2 does for /info, /options and /task/new/init; behaviour from the
    server's ``mode``: "token" (every request: invalid token), "options" (an option list without
    ours), "init" (init refused)."""

    def log_message(self, *args: Any) -> None:
        pass

    def _json(self, data: Any) -> None:
        body = json.dumps(data).encode()
        self.send_response(200)
        self.send_header("Content-Type", "application/json; charset=utf-8")
        self.send_header("Content-Length", str(len(body)))
        self.end_headers()
        self.wfile.write(body)

    def do_GET(self) -> None:
        mode = self.server.mode  # type: ignore[attr-defined]
        self.server.requests.append(("GET", urlparse(self.path).path))  # type: ignore[attr-defined]
        if mode == "token":
            self._json({"error": "Invalid authentication token"})
        elif self.path.startswith("/info"):
            self._json({"version": "2.2.4", "engine": "odm", "engineVersion": "3.5.5", "taskQueueCount": 0})
        elif self.path.startswith("/options"):
            names = ["dsm", "orthophoto-resolution"] + ([] if mode == "options" else OUR_OPTIONS)
            self._json([{"name": n, "type": "string", "value": "", "domain": "", "help": ""} for n in names])
        else:
            self._json({"error": "not found"})

    def do_POST(self) -> None:
        length = int(self.headers.get("Content-Length") or 0)
        self.rfile.read(length)
        path = urlparse(self.path).path
        self.server.requests.append(("POST", path))  # type: ignore[attr-defined]
        if path == "/task/new/init" and self.server.mode == "slow":  # type: ignore[attr-defined]
            self._json({"uuid": self.headers.get("set-uuid")})
        elif path.startswith("/task/new/upload") and self.server.mode == "slow":  # type: ignore[attr-defined]
            # A slow link: every upload stays on the wire until the test has sent Ctrl-C.
            self.server.release.wait(30.0)  # type: ignore[attr-defined]
            self._json({"success": True})
        elif path == "/task/new/init":
            self._json({"error": "Invalid options: matcher-neighbors must be between 0 and 50"})
        else:
            self._json({"success": True})


class _QuietServer(ThreadingHTTPServer):
    def handle_error(self, request: Any, client_address: Any) -> None:
        pass  # a client that went away (Ctrl-C) mid-answer


@pytest.fixture
def peer() -> Iterator[ThreadingHTTPServer]:
    server = _QuietServer(("127.0.0.1", 0), _Peer)
    server.mode = "init"  # type: ignore[attr-defined]
    server.requests = []  # type: ignore[attr-defined]
    server.release = threading.Event()  # type: ignore[attr-defined]
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    yield server
    server.shutdown()
    server.server_close()


def _handoff(tmp_path: Path, url: str, token: str = "", ground: GroundOptions | None = None) -> None:
    if not (tmp_path / "img").exists():
        grid(tmp_path / "img", lines=2, per_line=4, dx_m=110.0, dy_m=45.0)
    handoff(
        tmp_path / "img",
        tmp_path / "work",
        HandoffOptions(
            engine=Engine.NODEODM,
            node_url=url,
            token=token,
            ground=GroundOptions(ground_elevation_m=0.0) if ground is None else ground,
        ),
    )


def test_a_wrong_token_is_named(tmp_path: Path, peer: ThreadingHTTPServer) -> None:
    peer.mode = "token"  # type: ignore[attr-defined]
    with pytest.raises(NodeError, match=r"refused the token.*--token"):
        _handoff(tmp_path, f"nodeodm://127.0.0.1:{peer.server_port}", token="nope")
    assert not (tmp_path / "work").exists()


def test_options_the_node_does_not_take_are_refused_before_upload(
    tmp_path: Path, peer: ThreadingHTTPServer
) -> None:
    peer.mode = "options"  # type: ignore[attr-defined]
    with pytest.raises(NodeError, match="does not take the option"):
        _handoff(tmp_path, f"nodeodm://127.0.0.1:{peer.server_port}")
    assert ("POST", "/task/new/init") not in peer.requests  # type: ignore[attr-defined]
    assert not (tmp_path / "work").exists()


def test_a_refused_task_is_named_and_cleaned_up(tmp_path: Path, peer: ThreadingHTTPServer) -> None:
    with pytest.raises(NodeError, match=r"refused the task.*matcher-neighbors"):
        _handoff(tmp_path, f"nodeodm://127.0.0.1:{peer.server_port}")
    requests = peer.requests  # type: ignore[attr-defined]
    assert ("POST", "/task/new/init") in requests
    assert ("POST", "/task/remove") in requests  # nothing left on the node
    assert not (tmp_path / "work").exists()
    assert not [p for p in tmp_path.iterdir() if ".staging" in p.name]


_CTRL_C_CHILD = """
import sys
from pathlib import Path
from processing.handoff.nodeodm import NodeAddress, run_on_node
files = sorted(Path(sys.argv[2]).glob("*.jpg"))
print("started", flush=True)
run_on_node(NodeAddress(host="127.0.0.1", port=int(sys.argv[1]), https=False), token="", files=files,
            options=[], name="t", results_dir=Path(sys.argv[3]))
"""


def test_ctrl_c_during_the_upload_cancels_removes_and_exits(
    tmp_path: Path, peer: ThreadingHTTPServer
) -> None:
    peer.mode = "slow"  # type: ignore[attr-defined]
    grid(tmp_path / "img", lines=1, per_line=4, dx_m=110.0, dy_m=45.0)
    child = subprocess.Popen(
        [
            sys.executable,
            "-c",
            _CTRL_C_CHILD,
            str(peer.server_port),
            str(tmp_path / "img"),
            str(tmp_path / "r"),
        ],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    deadline = time.monotonic() + 60
    while not any(p.startswith("/task/new/upload") for _, p in peer.requests):  # type: ignore[attr-defined]
        assert time.monotonic() < deadline and child.poll() is None, child.communicate()
        time.sleep(0.05)
    child.send_signal(signal.SIGINT)
    time.sleep(5.0)  # the child takes the signal, stops its uploads and waits for those on the wire
    peer.release.set()  # type: ignore[attr-defined]
    start = time.monotonic()
    _, err = child.communicate(timeout=30)
    # The uploads on the wire (5 s each here) are waited for, then nothing keeps the process alive.
    assert time.monotonic() - start < 20.0
    assert "KeyboardInterrupt" in err
    posts = [p for method, p in peer.requests if method == "POST"]  # type: ignore[attr-defined]
    # NodeODM keeps a partial upload in its tmp/ until its clean-up timer; the one call that clears
    # it is the commit (files moved into a task, or the folder deleted), then cancel and remove.
    commit = posts.index(next(p for p in posts if p.startswith("/task/new/commit/")))
    assert posts.index("/task/cancel") > commit and posts.index("/task/remove") > commit
    assert not any(p.startswith("/task/new/upload") for p in posts[commit:]), (posts, err)  # nothing after it
    assert "left on the node: nothing" in err
    assert not (tmp_path / "r").exists()


@pytest.mark.slow
@pytest.mark.skipif(
    not os.environ.get("SFAP_NODEODM_URL"), reason="set SFAP_NODEODM_URL to a NodeODM (--test mode)"
)
@pytest.mark.parametrize(
    "ground", [GroundOptions(ground_elevation_m=0.0), GroundOptions()], ids=["ground", "no-ground"]
)
def test_a_real_node_runs_the_task_end_to_end(tmp_path: Path, ground: GroundOptions) -> None:
    url = os.environ["SFAP_NODEODM_URL"]
    try:
        # Absolute altitudes with no ground elevation too: the ODM project does not need one.
        _handoff(tmp_path, url, token=os.environ.get("SFAP_NODEODM_TOKEN", ""), ground=ground)
    except NodeError as error:
        # A node started with --test_fail_tasks fails every task: the message quotes its output.
        if os.environ.get("SFAP_NODEODM_EXPECT") == "fail":
            assert "task failed" in str(error)
            assert not (tmp_path / "work").exists()
            return
        raise
    report = json.loads((tmp_path / "work" / "report.json").read_text())
    assert report["nodeodm"]["uploaded_files"] == 8 + 1  # images + geo.txt
    assert report["nodeodm"]["results"], "no result files downloaded"


_REAL_CTRL_C_CHILD = """
import sys
from pathlib import Path
from processing.handoff.nodeodm import parse_node_url, run_on_node
files = sorted(Path(sys.argv[2]).glob("*.jpg"))
run_on_node(parse_node_url(sys.argv[1]), token=sys.argv[4], files=files, options=[], name="t",
            results_dir=Path(sys.argv[3]), progress=lambda t: print(t, file=sys.stderr, flush=True))
"""


@pytest.mark.slow
@pytest.mark.skipif(
    not os.environ.get("SFAP_NODEODM_URL"), reason="set SFAP_NODEODM_URL to a NodeODM (--test mode)"
)
def test_ctrl_c_during_the_upload_leaves_nothing_on_a_real_node(tmp_path: Path) -> None:
    """Ctrl-C while the frames are on the wire: the task and the partial upload in the node's tmp/ are
    gone, as the node's own API tells (an upload to the task's UUID: "Invalid uuid (not found)",
    which NodeODM answers when tmp/<uuid>/body.json does not exist; the task list without it)."""
    from pyodm import Node
    from pyodm.exceptions import NodeResponseError

    url = os.environ["SFAP_NODEODM_URL"]
    token = os.environ.get("SFAP_NODEODM_TOKEN", "")
    folder = tmp_path / "img"
    folder.mkdir()
    rng = np.random.default_rng(1)
    for k in range(150):  # 150 frames of 2 MB of noise: long enough on the wire to be interrupted
        (folder / f"F{k:03d}.jpg").write_bytes(rng.integers(0, 256, 2_000_000, dtype=np.uint8).tobytes())
    child = subprocess.Popen(
        [sys.executable, "-c", _REAL_CTRL_C_CHILD, url, str(folder), str(tmp_path / "r"), token],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    assert child.stderr is not None
    seen = []
    for line in child.stderr:
        seen.append(line)
        if line.startswith("upload:") and not line.startswith("upload: 0%"):
            break
    child.send_signal(signal.SIGINT)
    _, rest = child.communicate(timeout=60)
    err = "".join(seen) + rest
    if "upload: 100%" in err:
        pytest.skip("the upload ended before Ctrl-C reached the child (a machine this loaded is too slow)")
    assert "KeyboardInterrupt" in err, err
    found = re.search(r"task ([0-9a-f]{8}-[0-9a-f]{4}-[0-9a-f]{4}-[0-9a-f]{4}-[0-9a-f]{12})", err)
    assert found, err
    task_uuid = found.group(1)
    node = Node.from_url(url)
    node.token = token
    assert task_uuid not in [t["uuid"] if isinstance(t, dict) else t for t in node.get("/task/list")]
    with pytest.raises(NodeResponseError, match=r"^Invalid uuid \(not found\)$"):
        node.post(f"/task/new/upload/{task_uuid}", data=b"")
    assert "left on the node: nothing" in err
