"""Reads a MAVLink telemetry log with pymavlink's mavutil, as MAVProxy and
log tools do, and prints what it holds as JSON: per message type the count,
and every ATTITUDE and GLOBAL_POSITION_INT with its fields and the record's
receive time. Usage: read_tlog.py IN.tlog
"""
import json
import sys

from pymavlink import mavutil


def main(path):
    log = mavutil.mavlink_connection(path, dialect="common", robust_parsing=False)
    counts = {}
    attitude = []
    position = []
    bad = 0
    while True:
        msg = log.recv_match()
        if msg is None:
            break
        kind = msg.get_type()
        if kind == "BAD_DATA":
            bad += 1
            continue
        counts[kind] = counts.get(kind, 0) + 1
        if kind == "ATTITUDE":
            attitude.append([msg.time_boot_ms, msg.roll, msg.pitch, msg.yaw])
        elif kind == "GLOBAL_POSITION_INT":
            position.append(
                [
                    msg.time_boot_ms,
                    msg.lat,
                    msg.lon,
                    msg.alt,
                    msg.relative_alt,
                    msg._timestamp,
                    msg.vx,
                    msg.vy,
                ]
            )
    json.dump(
        {"counts": counts, "bad": bad, "attitude": attitude, "position": position},
        sys.stdout,
    )


if __name__ == "__main__":
    main(sys.argv[1])
