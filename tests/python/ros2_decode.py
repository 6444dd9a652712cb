"""Decodes CDR payload files with rosbags, px4_msgs registered from their
.msg text: `ros2_decode.py MSG_DIR TYPE=FILE...` prints one JSON object per
file, NaN as null."""

import json
import math
import pathlib
import sys

from rosbags.typesys import Stores, get_typestore, get_types_from_msg


def plain(value):
    if hasattr(value, "__dataclass_fields__"):
        return {k: plain(getattr(value, k)) for k in value.__dataclass_fields__ if k != "__msgtype__"}
    if hasattr(value, "tolist"):
        return plain(value.tolist())
    if isinstance(value, (list, tuple)):
        return [plain(v) for v in value]
    if isinstance(value, float):
        return None if math.isnan(value) else value
    return value


def main():
    msg_dir = pathlib.Path(sys.argv[1])
    store = get_typestore(Stores.ROS2_JAZZY)
    for path in sorted(msg_dir.glob("*.msg")):
        store.register(get_types_from_msg(path.read_text(), f"px4_msgs/msg/{path.stem}"))
    out = {}
    for arg in sys.argv[2:]:
        typename, _, file = arg.partition("=")
        out[file] = plain(store.deserialize_cdr(pathlib.Path(file).read_bytes(), typename))
    print(json.dumps(out, allow_nan=False))


if __name__ == "__main__":
    main()
