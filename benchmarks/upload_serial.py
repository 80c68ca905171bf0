"""Benchmark: upload a 500-item mission over a simulated 57600-baud serial link.

The ground station opens a real serial port (``serial:///dev/pts/N:57600``, a pseudo-terminal
through pyserial, the code path of a telemetry radio). A relay joins the pseudo-terminal to the
simulated vehicle and lets bytes through at 57600 baud, 8N1: 5760 bytes/s each way, each byte
delivered no sooner than the line could have carried it.

The floor is what the bytes themselves cost. The mission protocol is lock-step (the vehicle asks
for item n+1 only after it holds item n), so every request and every item crosses the line one
after the other: floor = (bytes of MISSION_COUNT + every request + every MISSION_ITEM_INT +
the final MISSION_ACK) / 5760 B/s, with the exact MAVLink 2 sizes pymavlink packs. The same for
the read-back that verifies the upload. The vehicle's telemetry (heartbeat, position,
attitude...) shares the downlink as on a real radio; ``--no-telemetry`` keeps it off the line,
as a ground station that sets the stream rates to 0 would.

Each run is the whole ``sfap upload mission.waypoints --connect serial:///dev/pts/N:57600``
process: Python start-up and imports, opening the port, waiting for the vehicle's heartbeat, the
upload and the verifying read-back. Its wall time against the floor (upload + read-back bytes) is
the ratio reported, over RUNS runs (at least 5), as minimum, median and maximum: the slow tail
is shown, not hidden in a median. Beside it, labelled as in-process: the upload and read-back
times sfap itself measures (``--json``), and the relay's per-message reaction times of the
simulated vehicle and of the ground station (median, 95th percentile, maximum).

Run:  .venv/bin/python benchmarks/upload_serial.py [--items 500] [--runs 5] [--autopilot ardupilot|px4]
"""

from __future__ import annotations

import argparse
import json
import logging
import os
import socket
import statistics
import subprocess
import sys
import tempfile
import threading
import time
import tty
from pathlib import Path
from typing import Any

from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from acquisition.mavlink_items import to_mission_item_int
from acquisition.simulator.server import SimulatedVehicle
from acquisition.transfer import home_item
from planner.formats.waypoints import write_waypoints
from planner.mission import Autopilot, HomePosition, Mission, MissionItem

BAUD = 57600
BYTES_PER_S = BAUD / 10  # 8 data bits, 1 start, 1 stop
HOME = HomePosition(lat_deg=41.6488, lon_deg=-0.8891, alt_amsl_m=210.0)
_MISSION_MESSAGES = {
    mavlink2.MAVLINK_MSG_ID_MISSION_REQUEST,
    mavlink2.MAVLINK_MSG_ID_MISSION_REQUEST_INT,
    mavlink2.MAVLINK_MSG_ID_MISSION_COUNT,
    mavlink2.MAVLINK_MSG_ID_MISSION_ITEM_INT,
    mavlink2.MAVLINK_MSG_ID_MISSION_ITEM,
    mavlink2.MAVLINK_MSG_ID_MISSION_ACK,
}


def survey(count: int) -> Mission:
    items = [MissionItem.takeoff(HOME.lat_deg, HOME.lon_deg, 40.0)]
    items.append(MissionItem.cam_trigger_distance(24.3))
    i = 0
    while len(items) < count - 1:
        items.append(
            MissionItem.waypoint(
                HOME.lat_deg + 0.0001234567 * (i // 2), HOME.lon_deg + 0.0023 * (i % 2), 62.5
            )
        )
        i += 1
    items.append(MissionItem.return_to_launch())
    return Mission(items=tuple(items), home=HOME)


class PacedRelay:
    """Joins a pseudo-terminal master to a TCP peer at ``bytes_per_s`` each way."""

    def __init__(self, master_fd: int, peer: socket.socket, bytes_per_s: float, telemetry: bool):
        self.master_fd = master_fd
        self.peer = peer
        self.bytes_per_s = bytes_per_s
        self.telemetry = telemetry
        self.stop = threading.Event()
        self.bytes_up = 0  # ground station -> vehicle
        self.bytes_down = 0
        # reaction times (s): from a chunk handed to one side to the next chunk coming back
        self.gcs_reaction_s: list[float] = []
        self.vehicle_reaction_s: list[float] = []
        self._to_gcs_at: float | None = None
        self._to_vehicle_at: float | None = None
        self.threads = [
            threading.Thread(target=self._up, daemon=True),
            threading.Thread(target=self._down, daemon=True),
        ]

    def start(self) -> None:
        for thread in self.threads:
            thread.start()

    def close(self) -> None:
        self.stop.set()

    def _pace(self, n: int, state: dict[str, float]) -> None:
        # The line carries one byte every 1/bytes_per_s s; a chunk is out when its last byte is.
        start = max(time.monotonic(), state["free"])
        done = start + n / self.bytes_per_s
        state["free"] = done
        delay = done - time.monotonic()
        if delay > 0:
            time.sleep(delay)

    def _up(self) -> None:
        state = {"free": 0.0}
        while not self.stop.is_set():
            try:
                data = os.read(self.master_fd, 256)
            except OSError:
                return
            if not data:
                return
            if self._to_gcs_at is not None:
                self.gcs_reaction_s.append(time.monotonic() - self._to_gcs_at)
                self._to_gcs_at = None
            self._pace(len(data), state)
            self.bytes_up += len(data)
            try:
                self.peer.sendall(data)
            except OSError:
                return
            self._to_vehicle_at = time.monotonic()

    def _down(self) -> None:
        state = {"free": 0.0}
        parser = mavlink2.MAVLink(None)
        parser.robust_parsing = True
        while not self.stop.is_set():
            try:
                data = self.peer.recv(256)
            except OSError:
                return
            if not data:
                return
            if self._to_vehicle_at is not None:
                self.vehicle_reaction_s.append(time.monotonic() - self._to_vehicle_at)
                self._to_vehicle_at = None
            if not self.telemetry:
                messages = parser.parse_buffer(data) or []
                data = b"".join(
                    bytes(m.get_msgbuf())
                    for m in messages
                    if m.get_msgId() in _MISSION_MESSAGES or m.get_type() == "HEARTBEAT"
                )
                if not data:
                    continue
            self._pace(len(data), state)
            self.bytes_down += len(data)
            try:
                os.write(self.master_fd, data)
            except OSError:
                return
            self._to_gcs_at = time.monotonic()


def packed_size(message: Any) -> int:
    return len(message.pack(mavlink2.MAVLink(None, srcSystem=1, srcComponent=1)))


def floor_bytes(mission: Mission, autopilot: Autopilot) -> tuple[int, int]:
    """Bytes that must cross the line for the upload and for the verifying read-back."""
    items = ([home_item(mission.home)] if autopilot is Autopilot.ARDUPILOT else []) + list(mission.items)
    n = len(items)
    request_cls = (
        mavlink2.MAVLink_mission_request_message
        if autopilot is Autopilot.ARDUPILOT
        else mavlink2.MAVLink_mission_request_int_message
    )
    items_bytes = sum(packed_size(to_mission_item_int(item, seq, 1, 1)) for seq, item in enumerate(items))
    requests = sum(packed_size(request_cls(255, 190, seq, 0)) for seq in range(n))
    count = packed_size(mavlink2.MAVLink_mission_count_message(1, 1, n, 0))
    ack = packed_size(mavlink2.MAVLink_mission_ack_message(255, 190, 0, 0))
    upload = count + requests + items_bytes + ack
    read_requests = sum(
        packed_size(mavlink2.MAVLink_mission_request_int_message(1, 1, seq, 0)) for seq in range(n)
    )
    request_list = packed_size(mavlink2.MAVLink_mission_request_list_message(1, 1, 0))
    # what reads back is what was stored: the same item sizes, give or take trimmed zeros
    verify = request_list + count + read_requests + items_bytes + ack
    return upload, verify


def _percentile(values: list[float], q: float) -> float:
    ordered = sorted(values)
    return ordered[min(len(ordered) - 1, round(q * (len(ordered) - 1)))]


def run(mission_file: Path, mission: Mission, autopilot: Autopilot, telemetry: bool) -> dict[str, Any]:
    """One whole ``sfap upload`` process against a fresh simulated vehicle behind the paced line."""
    master, slave = os.openpty()
    tty.setraw(slave)
    device = os.ttyname(slave)
    sfap = str(Path(sys.executable).with_name("sfap"))
    with SimulatedVehicle(autopilot=autopilot, boot_delay_s=0.0, streams_on_request=False) as vehicle:
        host, port = vehicle.url_for_client.removeprefix("tcp://").split(":")
        peer = socket.create_connection((host, int(port)))
        peer.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        relay = PacedRelay(master, peer, BYTES_PER_S, telemetry)
        relay.start()
        try:
            start = time.perf_counter()
            done = subprocess.run(
                [sfap, "upload", str(mission_file), "--connect", f"serial://{device}:{BAUD}", "--json"],
                capture_output=True,
                text=True,
            )
            process_s = time.perf_counter() - start
        finally:
            relay.close()
            peer.close()
            os.close(slave)
            os.close(master)
    if done.returncode != 0:
        sys.exit(f"sfap upload failed ({done.returncode}):\n{done.stderr[-2000:]}")
    report = json.loads(done.stdout)
    floor_up, floor_verify = floor_bytes(mission, autopilot)
    floor_s = (floor_up + floor_verify) / BYTES_PER_S
    return {
        "process_s": process_s,
        "floor_s": floor_s,
        "ratio": process_s / floor_s,
        "upload_s": report.get("upload_s"),
        "verify_s": report.get("verify_s"),
        "upload_floor_s": floor_up / BYTES_PER_S,
        "verify_floor_s": floor_verify / BYTES_PER_S,
        "vehicle_reaction_s": relay.vehicle_reaction_s,
        "gcs_reaction_s": relay.gcs_reaction_s,
    }


def main() -> int:
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    from paired import machine

    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--items", type=int, default=500)
    parser.add_argument("--runs", type=int, default=5)
    parser.add_argument("--autopilot", choices=[a.value for a in Autopilot], default="ardupilot")
    parser.add_argument("--no-telemetry", action="store_true", help="keep telemetry off the line")
    args = parser.parse_args()
    logging.basicConfig(level=logging.ERROR)
    autopilot = Autopilot(args.autopilot)
    mission = survey(args.items)
    load_before = os.getloadavg()
    runs = []
    with tempfile.TemporaryDirectory(prefix="upload-bench-") as tmp:
        mission_file = Path(tmp) / "mission.waypoints"
        write_waypoints(mission, mission_file)
        for _ in range(args.runs):
            runs.append(run(mission_file, mission, autopilot, telemetry=not args.no_telemetry))
    load_after = os.getloadavg()
    ratios = [r["ratio"] for r in runs]
    print(machine())
    print(
        f"{args.items} items to {autopilot.value} over a simulated {BAUD}-baud serial link "
        f"(telemetry on the link: {not args.no_telemetry}); {len(runs)} runs, "
        f"{time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}"
    )
    print(
        f"  whole sfap upload process (start-up, port, heartbeat wait, upload, read-back): "
        f"{', '.join(format(r['process_s'], '.2f') for r in runs)} s; floor {runs[0]['floor_s']:.2f} s"
    )
    print(
        f"  ratio to the floor: min {min(ratios):.3f}  median {statistics.median(ratios):.3f}  "
        f"max {max(ratios):.3f}"
    )
    up = [r["upload_s"] / r["upload_floor_s"] for r in runs if r["upload_s"]]
    verify = [r["verify_s"] / r["verify_floor_s"] for r in runs if r["verify_s"]]
    if up and verify:
        print(
            f"  in process (labelled; sfap's own timing of the transfer alone): upload ratio "
            f"{min(up):.3f}-{max(up):.3f}, read-back ratio {min(verify):.3f}-{max(verify):.3f}"
        )
    vehicle = [x for r in runs for x in r["vehicle_reaction_s"]]
    gcs = [x for r in runs for x in r["gcs_reaction_s"]]
    for label, values in (("simulated vehicle", vehicle), ("ground station (sfap)", gcs)):
        if values:
            print(
                f"  reaction per message, {label}: median {statistics.median(values) * 1e3:.2f} ms, "
                f"95th percentile {_percentile(values, 0.95) * 1e3:.2f} ms, "
                f"max {max(values) * 1e3:.1f} ms ({len(values)} messages)"
            )
    print(f"  load average before {' '.join(f'{v:.2f}' for v in load_before)}, "
          f"after {' '.join(f'{v:.2f}' for v in load_after)}")  # fmt: skip
    return 0


if __name__ == "__main__":
    sys.exit(main())
