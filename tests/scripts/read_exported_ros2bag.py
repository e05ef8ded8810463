"""Reads a ROS 2 bag directory exported by froctomap with an independent reader (PyPI
rosbags) and reports what it holds, for the recording tests.

Usage: python read_exported_ros2bag.py BAG_DIR OUT_DIR
The directory is opened by rosbags' rosbag2 Reader (its metadata.yaml, then the MCAP storage
file it names). Each connection's types are registered into an empty typestore from the
message definition the MCAP file stores (ros2msg), and every message of every topic is
deserialised as CDR with them; OUT_DIR/<log_time>.data gets each octomap message's `data`.
metadata.yaml is also parsed on its own (ruamel.yaml, as rosbags does) and its fields
reported as they are. Prints one JSON object: the raw metadata, what the reader says (start,
end, duration, message count, compression, connections with their serialisation format and
count), the messages decoded per topic, and per octomap message its log time, header stamp
and frame, binary, id and resolution.
"""
import collections
import json
import os
import sys
from pathlib import Path

from rosbags.rosbag2 import Reader
from rosbags.typesys import Stores, get_types_from_msg, get_typestore
from ruamel.yaml import YAML


def main(path, out_dir):
    path = Path(path)
    raw = YAML(typ="safe").load((path / "metadata.yaml").read_text("utf8"))
    store = get_typestore(Stores.EMPTY)
    report = {"metadata": raw, "connections": [], "octomaps": []}
    decoded = collections.Counter()
    with Reader(path) as reader:
        report["start_time"] = reader.start_time
        report["end_time"] = reader.end_time
        report["duration"] = reader.duration
        report["message_count"] = reader.message_count
        # None when the bag has none (rosbags gives "" or None for an empty mode).
        report["compression"] = [
            reader.compression_mode or None,
            reader.compression_format or None,
        ]
        for connection in reader.connections:
            types = get_types_from_msg(connection.msgdef.data, connection.msgtype)
            store.register({k: v for k, v in types.items() if k not in store.types})
            report["connections"].append({
                "topic": connection.topic,
                "type": connection.msgtype,
                "format": connection.ext.serialization_format,
                "count": connection.msgcount,
            })
        for connection, log_time, data in reader.messages():
            message = store.deserialize_cdr(data, connection.msgtype)
            decoded[connection.topic] += 1
            if connection.msgtype != "octomap_msgs/msg/Octomap":
                continue
            with open(os.path.join(out_dir, f"{log_time}.data"), "wb") as out:
                out.write(message.data.tobytes())
            stamp = message.header.stamp
            report["octomaps"].append({
                "topic": connection.topic,
                "log_time": log_time,
                "stamp_ns": stamp.sec * 1_000_000_000 + stamp.nanosec,
                "frame_id": message.header.frame_id,
                "binary": bool(message.binary),
                "id": message.id,
                "resolution": message.resolution,
            })
    report["decoded"] = dict(decoded)
    print(json.dumps(report))


if __name__ == "__main__":
    main(*sys.argv[1:3])
