"""Listens on a MAVLink UDP port with pymavlink, an implementation independent
of the edge's, and prints what arrived as JSON: every decoded message with
its header and arrival time, and how many frames failed to decode (bad CRC,
unknown id, broken framing).

    python3 mavlink_listen.py PORT SECONDS [REPLY]

It stops after SECONDS, or as soon as its standard input closes.
With REPLY, it also plays the autopilot's side once a second: a TIMESYNC
request, which the edge must answer, and a GLOBAL_POSITION_INT.
"""

import json
import os
import sys
import threading
import time

os.environ["MAVLINK20"] = "1"
from pymavlink import mavutil  # noqa: E402

port, seconds = int(sys.argv[1]), float(sys.argv[2])
reply = len(sys.argv) > 3
conn = mavutil.mavlink_connection(
    f"udpin:127.0.0.1:{port}", dialect="common", robust_parsing=True, source_system=1, source_component=1
)
stop = threading.Event()
threading.Thread(target=lambda: (sys.stdin.read(), stop.set()), daemon=True).start()
print("listening", file=sys.stderr, flush=True)
messages, bad = [], 0
start = time.monotonic()
next_sync = start + 1.0
while time.monotonic() - start < seconds and not stop.is_set():
    msg = conn.recv_match(blocking=True, timeout=0.2)
    now = time.monotonic() - start
    # Once the edge has been heard, pymavlink knows where to reply.
    if reply and messages and time.monotonic() >= next_sync:
        conn.mav.timesync_send(0, int(now * 1e9))
        # Its own GNSS position, as an autopilot streams it: 30.5205 N,
        # 114.3601 E, 50 m above mean sea level, heading east.
        conn.mav.global_position_int_send(int(now * 1e3), 305205000, 1143601000, 50000, 30000, 0, 0, 0, 9000)
        next_sync += 1.0
    if msg is None:
        continue
    kind = msg.get_type()
    if kind == "BAD_DATA":
        bad += 1
        continue
    fields = msg.to_dict()
    fields.pop("mavpackettype", None)
    messages.append(
        {
            "type": kind,
            "t": now,
            "sys": msg.get_srcSystem(),
            "comp": msg.get_srcComponent(),
            "seq": msg.get_seq(),
            "v2": msg.get_msgbuf()[0] == 0xFD,
            "fields": fields,
        }
    )
json.dump({"bad": bad, "messages": messages}, sys.stdout, default=str)
