"""An rmw_zenoh-style listener, independent of towernav: eclipse-zenoh for
the keys, liveliness tokens and attachments; rosbags for CDR and ROS 2 type
hashes (px4_msgs registered from their .msg text); pycdr2 for PX4's XCDR2.

Connects to --connect (a router) for --seconds while publishing a PX4 vehicle_attitude
(heading east, its clock at --px4-clock-us), and writes what it saw as JSON.
"""

import argparse
from dataclasses import dataclass
import json
import math
import pathlib
import struct
import threading
import time

import numpy
import zenoh
from rosbags.typesys import Stores, get_typestore, get_types_from_msg
from pycdr2 import IdlStruct
from pycdr2.types import float32, float64, uint8, uint64

PX4 = ["AuxGlobalPosition", "VehicleGlobalPosition", "VehicleAttitude", "VehicleStatus"]


@dataclass
class AuxGlobalPosition(IdlStruct, typename="px4_msgs/msg/AuxGlobalPosition"):
    timestamp: uint64
    timestamp_sample: uint64
    id: uint8
    source: uint8
    lat: float64
    lon: float64
    alt: float32
    eph: float32
    epv: float32
    lat_lon_reset_counter: uint8


def typestore(msg_dir):
    store = get_typestore(Stores.ROS2_JAZZY)
    for name in PX4:
        text = (msg_dir / f"{name}.msg").read_text()
        store.register(get_types_from_msg(text, f"px4_msgs/msg/{name}"))
    return store


def plain(value):
    """A decoded message as JSON-able values (NaN as None)."""
    if hasattr(value, "__dataclass_fields__"):
        return {k: plain(getattr(value, k)) for k in value.__dataclass_fields__ if k != "__msgtype__"}
    if isinstance(value, dict):
        return {k: plain(v) for k, v in value.items()}
    if hasattr(value, "tolist"):
        return plain(value.tolist())
    if isinstance(value, (list, tuple)):
        return [plain(v) for v in value]
    if isinstance(value, (float, numpy.floating)):
        return None if math.isnan(value) else float(value)
    if isinstance(value, numpy.integer):
        return int(value)
    return value


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--connect", required=True)
    parser.add_argument("--seconds", type=float, required=True)
    parser.add_argument("--msg-dir", required=True)
    parser.add_argument("--px4-clock-us", type=int, default=5_000_000_000)
    parser.add_argument("--out", required=True)
    args = parser.parse_args()
    store = typestore(pathlib.Path(args.msg_dir))
    hashes = {
        t: store.hash_rihs01(t)
        for t in [
            "sensor_msgs/msg/NavSatFix",
            "geometry_msgs/msg/PoseWithCovarianceStamped",
            "nav_msgs/msg/Odometry",
        ]
        + [f"px4_msgs/msg/{n}" for n in PX4]
    }

    conf = zenoh.Config()
    conf.insert_json5("mode", '"peer"')
    conf.insert_json5("connect/endpoints", json.dumps([args.connect]))
    conf.insert_json5("scouting/multicast/enabled", "false")
    session = zenoh.open(conf)

    samples, tokens, lock = [], [], threading.Lock()

    def on_sample(sample):
        attachment = sample.attachment.to_bytes() if sample.attachment is not None else b""
        with lock:
            samples.append((str(sample.key_expr), sample.payload.to_bytes(), attachment))

    def on_token(sample):
        with lock:
            tokens.append((str(sample.key_expr), str(sample.kind)))

    sub = session.declare_subscriber("0/**", on_sample)
    live = session.liveliness().declare_subscriber("@ros2_lv/**", on_token, history=True)
    attitude_key = (
        "0/fmu/out/vehicle_attitude/px4_msgs::msg::dds_::VehicleAttitude_/"
        + hashes["px4_msgs/msg/VehicleAttitude"]
    )
    Attitude = store.types["px4_msgs/msg/VehicleAttitude"]
    half = math.pi / 4  # heading east
    start = time.monotonic()
    alive_at_end = []
    while time.monotonic() - start < args.seconds:
        clock = args.px4_clock_us + int((time.monotonic() - start) * 1e6)
        msg = Attitude(
            timestamp=clock,
            timestamp_sample=clock,
            q=numpy.array([math.cos(half), 0, 0, math.sin(half)], dtype="float32"),
            delta_q_reset=numpy.array([1, 0, 0, 0], dtype="float32"),
            quat_reset_counter=0,
        )
        session.put(attitude_key, bytes(store.serialize_cdr(msg, "px4_msgs/msg/VehicleAttitude")))
        time.sleep(0.02)
        if not alive_at_end and time.monotonic() - start > args.seconds * 0.6:
            for reply in session.liveliness().get("@ros2_lv/**", timeout=2.0):
                if reply.ok is not None:
                    alive_at_end.append(str(reply.ok.key_expr))
    sub.undeclare()
    live.undeclare()

    decoded = {}
    for key, payload, attachment in samples:
        if "/fmu/out/" in key:
            continue
        parts = key.split("/")
        dds_type = parts[-2]
        pkg, _, _, name = dds_type.split("::")
        typename = f"{pkg}/msg/{name.rstrip('_')}"
        entry = {"key": key, "header": payload[:4].hex()}
        if typename == "px4_msgs/msg/AuxGlobalPosition" and payload[1] == 0x07:
            m = AuxGlobalPosition.deserialize(payload)
            entry["msg"] = plain({k: getattr(m, k) for k in AuxGlobalPosition.__annotations__})
        else:
            entry["msg"] = plain(store.deserialize_cdr(payload, typename))
        if len(attachment) == 33:
            seq, stamp, n = struct.unpack_from("<qqB", attachment)
            entry["attachment"] = {"sequence": seq, "unix_ns": stamp, "gid_len": n, "gid": attachment[17:].hex()}
        else:
            entry["attachment"] = {"raw": attachment.hex()}
        decoded.setdefault(typename, []).append(entry)

    pathlib.Path(args.out).write_text(
        json.dumps(
            {"hashes": hashes, "tokens": tokens, "alive": alive_at_end, "topics": decoded, "attitude_key": attitude_key},
            indent=1,
            allow_nan=False,
        )
    )
    session.close()


if __name__ == "__main__":
    main()
