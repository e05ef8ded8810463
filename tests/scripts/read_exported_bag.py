"""Reads a ROS 1 bag exported by froctomap with an independent reader (PyPI rosbags) and
reports what it holds, for the recording tests.

Usage: python read_exported_bag.py FILE.bag OUT_DIR
The bag is opened by rosbags' indexed reader (the bag header, connection and chunk-info
records); each connection's type is registered from the message definition the bag stores,
and rosbags computes that definition's MD5 sum itself, to compare with the one the bag says.
Every message is deserialised as ROS 1; OUT_DIR/<log_time>.data gets its `data` field. Prints
one JSON object: the connections (topic, type, stored and computed MD5, message count), the
bag's message count, and per message its log time, header (seq, stamp, frame), binary, id
and resolution.
"""
import json
import os
import sys

from rosbags.rosbag1 import Reader
from rosbags.typesys import Stores, get_types_from_msg, get_typestore


def main(path, out_dir):
    store = get_typestore(Stores.ROS1_NOETIC)
    report = {"connections": [], "messages": []}
    with Reader(path) as reader:
        for connection in reader.connections:
            store.register(get_types_from_msg(connection.msgdef.data, connection.msgtype))
            _, computed = store.generate_msgdef(connection.msgtype, ros_version=1)
            report["connections"].append({
                "topic": connection.topic,
                "type": connection.msgtype,
                "md5": connection.digest,
                "computed_md5": computed,
                "count": connection.msgcount,
            })
        report["count"] = reader.message_count
        for connection, log_time, raw in reader.messages():
            message = store.deserialize_ros1(raw, connection.msgtype)
            with open(os.path.join(out_dir, f"{log_time}.data"), "wb") as out:
                out.write(message.data.tobytes())
            stamp = message.header.stamp
            report["messages"].append({
                "topic": connection.topic,
                "log_time": log_time,
                "seq": message.header.seq,
                "stamp_ns": stamp.sec * 1_000_000_000 + stamp.nanosec,
                "frame_id": message.header.frame_id,
                "binary": bool(message.binary),
                "id": message.id,
                "resolution": message.resolution,
            })
    print(json.dumps(report))


if __name__ == "__main__":
    main(*sys.argv[1:3])
