"""Writes a MAVLink telemetry log with pymavlink, as ground stations do:
each record is the receive time (big-endian u64 microseconds since the
epoch) and one MAVLink 2 frame. Usage: write_tlog.py OUT.tlog

The vehicle (system 1) sends ATTITUDE at 50 Hz, GLOBAL_POSITION_INT and
ALTITUDE (stamped in boot time, altitude_monotonic climbing 5 cm a
message) at 10 Hz and GPS_RAW_INT (3-D fix, its own stamp in Unix time) at 5 Hz, each
received 20 ms after it was sent; a ground station (system 255) sends
HEARTBEAT and a second vehicle (system 2) sends ATTITUDE of its own.
"""
import math
import struct
import sys

from pymavlink.dialects.v20 import common as mavlink

EPOCH_US = 1_764_000_000_000_000
DELAY_US = 20_000


def main(path):
    with open(path, "wb") as f:
        links = {s: mavlink.MAVLink(f, srcSystem=s, srcComponent=1) for s in (1, 2, 255)}

        def put(system, boot_ms, msg):
            stamp = EPOCH_US + boot_ms * 1000 + DELAY_US
            f.write(struct.pack(">Q", stamp) + msg.pack(links[system]))

        for i in range(500):
            boot_ms = 10_000 + 20 * i
            t = boot_ms / 1000.0
            put(1, boot_ms, mavlink.MAVLink_attitude_message(
                boot_ms, 0.2 * math.sin(t), 0.1 * math.cos(t), math.remainder(0.3 * t, 2 * math.pi),
                0.0, 0.0, 0.0))
            put(2, boot_ms, mavlink.MAVLink_attitude_message(boot_ms, 1.0, 1.0, 1.0, 0.0, 0.0, 0.0))
            if i % 5 == 0:
                put(1, boot_ms, mavlink.MAVLink_global_position_int_message(
                    boot_ms, int(47.1e7) + i * 10, int(8.5e7) + i * 5, 512_000 + i, 30_000, 0, 0, 0, 0))
                put(1, boot_ms, mavlink.MAVLink_altitude_message(
                    boot_ms * 1000, 100.0 + 0.01 * i, 512.0, 30.0, 30.0, 30.0, float("nan")))
                put(2, boot_ms, mavlink.MAVLink_altitude_message(
                    boot_ms * 1000, -50.0, 0.0, 0.0, 0.0, 0.0, 0.0))
            if i % 10 == 0:
                put(1, boot_ms, mavlink.MAVLink_gps_raw_int_message(
                    EPOCH_US + boot_ms * 1000, 3, int(47.1e7) + i * 10, int(8.5e7) + i * 5,
                    512_000 + i, 90, 120, 0, 0, 12))
                put(255, boot_ms, mavlink.MAVLink_heartbeat_message(6, 8, 0, 0, 4, 3))


if __name__ == "__main__":
    main(sys.argv[1])
