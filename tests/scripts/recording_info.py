"""Prints what independent readers say a recording holds, as JSON: per topic its type, message
count and first and last log times (ns). ROS 1 bags and ROS 2 bag directories are read with
PyPI rosbags' AnyReader, MCAP files with PyPI mcap.

Usage: python recording_info.py PATH
"""
import json
import sys
from pathlib import Path


def tally(topics, topic, msgtype, t):
    entry = topics.setdefault(topic, {"type": msgtype, "messages": 0, "first": t, "last": t})
    entry["messages"] += 1
    entry["first"] = t if entry["first"] is None else min(entry["first"], t)
    entry["last"] = t if entry["last"] is None else max(entry["last"], t)


def main():
    path = Path(sys.argv[1])
    topics = {}
    if path.suffix == ".mcap":
        from mcap.reader import make_reader
        with open(path, "rb") as f:
            reader = make_reader(f)
            for schema, channel, message in reader.iter_messages():
                tally(topics, channel.topic, schema.name, message.log_time)
    else:
        from rosbags.highlevel import AnyReader
        with AnyReader([path]) as reader:
            for connection in reader.connections:
                topics.setdefault(connection.topic, {"type": connection.msgtype, "messages": 0,
                                                     "first": None, "last": None})
            for connection, t, _ in reader.messages():
                tally(topics, connection.topic, connection.msgtype, t)
            counts = {c.topic: c.msgcount for c in reader.connections}
            assert all(topics[t]["messages"] == n for t, n in counts.items()), counts
    print(json.dumps(topics))


main()
