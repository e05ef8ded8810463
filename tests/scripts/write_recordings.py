"""Writes ROS recordings of octomap maps with independent implementations (PyPI rosbags for
ROS 1 bags and ROS 2 bags with MCAP or sqlite3 storage, mcap-ros2-support for plain MCAP),
for the recording tests of froctomap.

Usage: python write_recordings.py SPEC.json
SPEC: {"recordings": [{"kind": "ros1" | "ros2bag" | "ros2sqlite" | "mcap", "path": ... ("-":
                        an MCAP stream on standard output, written in order without seeking),
                       "compression": "none" | "bz2" | "lz4" | "zstd"
                                      (ros2sqlite: "none" | "message" | "file", zstd),
                       "chunk_bytes": int (optional: a chunk ends past this size),
                       "messages": [{"topic": ..., "map": FILE.bt, "stamp_ns": int,
                                     "log_ns": int, "whole_file": bool}]}]}
Each recording also gets a /chatter std_msgs/String message, a topic of another type.
"""
import io
import json
import sys

import numpy as np
from rosbags.typesys import Stores, get_types_from_msg, get_typestore

OCTOMAP = "octomap_msgs/msg/Octomap"
OCTOMAP_MSG = """std_msgs/Header header
bool binary
string id
float64 resolution
int8[] data
"""


def typestore(store):
    ts = get_typestore(store)
    ts.register(get_types_from_msg(OCTOMAP_MSG, OCTOMAP))
    return ts


def map_parts(path, whole_file):
    raw = open(path, "rb").read()
    head, body = raw.split(b"\ndata\n", 1)
    res = next(float(line.split()[1]) for line in head.split(b"\n") if line.startswith(b"res "))
    return res, (raw if whole_file else body)


def message(ts, ros1, m):
    res, data = map_parts(m["map"], m.get("whole_file", False))
    Time = ts.types["builtin_interfaces/msg/Time"]
    Header = ts.types["std_msgs/msg/Header"]
    sec, nsec = divmod(m["stamp_ns"], 1_000_000_000)
    stamp = Time(sec=sec, nanosec=nsec)
    header = Header(seq=0, stamp=stamp, frame_id="map") if ros1 else Header(stamp=stamp, frame_id="map")
    return ts.types[OCTOMAP](header=header, binary=True, id="OcTree", resolution=res,
                             data=np.frombuffer(data, dtype=np.int8))


def chatter(ts):
    return ts.types["std_msgs/msg/String"](data="hello")


def write_ros1(spec):
    from rosbags.rosbag1 import Writer
    ts = typestore(Stores.ROS1_NOETIC)
    writer = Writer(spec["path"])
    fmt = {"bz2": Writer.CompressionFormat.BZ2, "lz4": Writer.CompressionFormat.LZ4}.get(spec["compression"])
    if fmt is not None:
        writer.set_compression(fmt)
    if "chunk_bytes" in spec:
        writer.chunk_threshold = spec["chunk_bytes"]
    with writer:
        connections = {}
        for m in spec["messages"]:
            if m["topic"] not in connections:
                connections[m["topic"]] = writer.add_connection(m["topic"], OCTOMAP, typestore=ts)
            data = ts.serialize_ros1(message(ts, True, m), OCTOMAP)
            writer.write(connections[m["topic"]], m["log_ns"], data)
        other = writer.add_connection("/chatter", "std_msgs/msg/String", typestore=ts)
        writer.write(other, spec["messages"][0]["log_ns"], ts.serialize_ros1(chatter(ts), "std_msgs/msg/String"))


def write_ros2bag(spec, storage="mcap"):
    from rosbags.rosbag2 import CompressionFormat, CompressionMode, StoragePlugin, Writer
    ts = typestore(Stores.ROS2_HUMBLE)
    plugin = {"mcap": StoragePlugin.MCAP, "sqlite3": StoragePlugin.SQLITE3}[storage]
    writer = Writer(spec["path"], version=8, storage_plugin=plugin)
    mode = {"message": CompressionMode.MESSAGE, "file": CompressionMode.FILE}.get(spec["compression"])
    if mode is not None:
        writer.set_compression(mode, CompressionFormat.ZSTD)
    with writer:
        connections = {}
        for m in spec["messages"]:
            if m["topic"] not in connections:
                connections[m["topic"]] = writer.add_connection(m["topic"], OCTOMAP, typestore=ts)
            data = ts.serialize_cdr(message(ts, False, m), OCTOMAP)
            writer.write(connections[m["topic"]], m["log_ns"], data)
        other = writer.add_connection("/chatter", "std_msgs/msg/String", typestore=ts)
        writer.write(other, spec["messages"][0]["log_ns"], ts.serialize_cdr(chatter(ts), "std_msgs/msg/String"))


class Pipe(io.RawIOBase):
    """Standard output as the MCAP writer needs it: it asks where it is (tell), never seeks."""

    def __init__(self, out):
        self.out, self.pos = out, 0

    def writable(self):
        return True

    def write(self, data):
        self.out.write(data)
        self.pos += len(data)
        return len(data)

    def tell(self):
        return self.pos

    def flush(self):
        self.out.flush()

    def close(self):
        self.out.flush()


def write_mcap(spec):
    from mcap.writer import CompressionType
    from mcap_ros2.writer import Writer
    ts = typestore(Stores.ROS2_HUMBLE)
    msgdef, _ = ts.generate_msgdef(OCTOMAP, ros_version=2)
    compression = {"none": CompressionType.NONE, "lz4": CompressionType.LZ4}.get(spec["compression"], CompressionType.ZSTD)
    stream = spec["path"] == "-"
    with (Pipe(sys.stdout.buffer) if stream else open(spec["path"], "wb")) as out:
        writer = Writer(out, compression=compression, chunk_size=spec.get("chunk_bytes", 1024 * 1024))
        schema = writer.register_msgdef(OCTOMAP, msgdef)
        string = writer.register_msgdef("std_msgs/msg/String", "string data\n")
        for m in spec["messages"]:
            res, data = map_parts(m["map"], m.get("whole_file", False))
            sec, nsec = divmod(m["stamp_ns"], 1_000_000_000)
            body = {"header": {"stamp": {"sec": sec, "nanosec": nsec}, "frame_id": "map"},
                    "binary": True, "id": "OcTree", "resolution": res, "data": list(np.frombuffer(data, dtype=np.int8))}
            writer.write_message(m["topic"], schema, body, log_time=m["log_ns"], publish_time=m["log_ns"])
        writer.write_message("/chatter", string, {"data": "hello"}, log_time=spec["messages"][0]["log_ns"])
        writer.finish()


def main():
    spec = json.load(open(sys.argv[1]))
    writers = {"ros1": write_ros1, "ros2bag": write_ros2bag, "mcap": write_mcap,
               "ros2sqlite": lambda spec: write_ros2bag(spec, "sqlite3")}
    for recording in spec["recordings"]:
        writers[recording["kind"]](recording)


main()
