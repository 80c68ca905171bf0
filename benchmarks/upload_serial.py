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

Run:  .venv/bin/python benchmarks/upload_serial.py [--items 500] [--autopilot ardupilot|px4]
"""

from __future__ import annotations

import argparse
import json
import logging
import os
import socket
import statistics
import sys
import threading
import time
import tty
from typing import Any

from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from acquisition.link import Link
from acquisition.mavlink_items import to_mission_item_int
from acquisition.simulator.server import SimulatedVehicle
from acquisition.transfer import home_item, upload_mission
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


def run(items: int, autopilot: Autopilot, telemetry: bool) -> dict[str, Any]:
    mission = survey(items)
    master, slave = os.openpty()
    tty.setraw(slave)
    device = os.ttyname(slave)
    with SimulatedVehicle(autopilot=autopilot, boot_delay_s=0.0, streams_on_request=False) as vehicle:
        host, port = vehicle.url_for_client.removeprefix("tcp://").split(":")
        peer = socket.create_connection((host, int(port)))
        peer.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        relay = PacedRelay(master, peer, BYTES_PER_S, telemetry)
        relay.start()
        try:
            with Link.open(f"serial://{device}:{BAUD}", heartbeat_timeout_s=10.0) as link:
                result = upload_mission(link, mission)
        finally:
            relay.close()
            peer.close()
            os.close(slave)
            os.close(master)
    floor_up, floor_verify = floor_bytes(mission, autopilot)
    vehicle_ms = statistics.median(relay.vehicle_reaction_s) * 1e3
    gcs_ms = statistics.median(relay.gcs_reaction_s) * 1e3
    n_wire = len(mission.items) + (1 if autopilot is Autopilot.ARDUPILOT else 0)
    floor_up_s = floor_up / BYTES_PER_S
    floor_verify_s = floor_verify / BYTES_PER_S
    return {
        "items": items,
        "autopilot": autopilot.value,
        "telemetry_on_link": telemetry,
        "baud": BAUD,
        "upload_s": round(result.upload_s, 3),
        "upload_floor_s": round(floor_up_s, 3),
        "upload_ratio": round(result.upload_s / floor_up_s, 3),
        "verify_s": round(result.verify_s, 3),
        "verify_floor_s": round(floor_verify_s, 3),
        "verify_ratio": round(result.verify_s / floor_verify_s, 3),
        "vehicle_reaction_ms_median": round(vehicle_ms, 2),
        "ground_station_reaction_ms_median": round(gcs_ms, 2),
        # the upload's ratio once the simulated vehicle's own reaction time is taken out
        "upload_ratio_without_vehicle_reaction": round(
            (result.upload_s - n_wire * vehicle_ms / 1e3) / floor_up_s, 3
        ),
        "items_resent": result.items_resent,
        "verified": result.verified,
    }


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--items", type=int, default=500)
    parser.add_argument("--autopilot", choices=[a.value for a in Autopilot], default="ardupilot")
    parser.add_argument("--no-telemetry", action="store_true", help="keep telemetry off the line")
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args()
    logging.basicConfig(level=logging.ERROR)
    figures = run(args.items, Autopilot(args.autopilot), telemetry=not args.no_telemetry)
    if args.json:
        print(json.dumps(figures, indent=2))
        return 0
    print(
        f"{figures['items']} items to {figures['autopilot']} over a simulated {BAUD}-baud serial "
        f"link (telemetry on the link: {figures['telemetry_on_link']})"
    )
    print(
        f"  upload     {figures['upload_s']:7.2f} s   floor {figures['upload_floor_s']:7.2f} s   "
        f"ratio {figures['upload_ratio']:.2f}  (target <= 1.30)"
    )
    print(
        f"  read-back  {figures['verify_s']:7.2f} s   floor {figures['verify_floor_s']:7.2f} s   "
        f"ratio {figures['verify_ratio']:.2f}"
    )
    print(
        f"  reaction per message (median): simulated vehicle "
        f"{figures['vehicle_reaction_ms_median']:.2f} ms, ground station "
        f"{figures['ground_station_reaction_ms_median']:.2f} ms; upload ratio without the "
        f"vehicle's reaction time {figures['upload_ratio_without_vehicle_reaction']:.2f}"
    )
    print(f"  verified: {figures['verified']}, items sent again: {figures['items_resent']}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
