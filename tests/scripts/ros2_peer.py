"""An independent ROS 2 peer for the froctomap node's interoperability test.

Eclipse Cyclone DDS (PyPI `cyclonedds`, the DDS of rmw_cyclonedds_cpp) with the
`octomap_msgs/msg/Octomap` type declared here as ROS 2 maps it to DDS
(`octomap_msgs::msg::dds_::Octomap_`, final, XCDR1). Confined to loopback: interface `lo`,
no multicast, the peer 127.0.0.1; Cyclone fails to start rather than use another interface.

Publishes the given `.bt`/`.ot` files (their body, as octomap_msgs' conversions do) on
`rt/<topic>`, reliable + transient-local (latched), stamped `--first-stamp` + i seconds: the
first one at once, the others after a line on stdin (the test sends it when the node has the
first map); then
waits for one message on `rt/froctomap/predicted` and writes it as a `.bt` file that upstream
OctoMap (octomap-python) must read. Prints one JSON line per event for the test to check.

Usage: ros2_peer.py --domain D --predicted-out OUT.bt [--topic /octomap_binary]
                    [--first-stamp SECONDS] [--timeout S] MAP...
"""

import argparse
import json
import os
import struct
import sys
import time
from dataclasses import dataclass

LOOPBACK_CONFIG = """<CycloneDDS><Domain Id="any"><General>
<Interfaces><NetworkInterface name="lo"/></Interfaces>
<AllowMulticast>false</AllowMulticast></General>
<Discovery><ParticipantIndex>auto</ParticipantIndex><MaxAutoParticipantIndex>30</MaxAutoParticipantIndex>
<Peers><Peer address="127.0.0.1"/></Peers></Discovery></Domain></CycloneDDS>"""


def say(**event):
    print(json.dumps(event), flush=True)


def split_map_file(data):
    """(binary, id, resolution, body) of a .bt or .ot file (upstream's text header)."""
    lines_end = data.index(b"\ndata\n") + len(b"\ndata\n")
    header = data[:lines_end].decode("ascii").splitlines()
    binary = header[0].startswith("# Octomap OcTree binary file")
    fields = {}
    for line in header[1:]:
        if line.startswith("#") or not line.strip():
            continue
        key, _, value = line.partition(" ")
        fields[key] = value.strip()
    return binary, fields["id"], float(fields["res"]), data[lines_end:]


def binary_node_count(body):
    """Nodes of a .bt body (2 bytes per inner node, 2 bits per child: 01 free leaf,
    10 occupied leaf, 11 inner), counted the way upstream's size() counts them."""
    count, pos, stack = 0, 0, [1]
    while stack:
        stack[-1] -= 1
        if stack[-1] < 0:
            stack.pop()
            continue
        # One node: read its child bits.
        count += 1
        (bits,) = struct.unpack_from("<H", body, pos)
        pos += 2
        inner = 0
        for child in range(8):
            kind = (bits >> (2 * child)) & 3
            if kind == 3:
                inner += 1
            elif kind in (1, 2):
                count += 1
        if inner:
            stack.append(inner)
    return count


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--domain", type=int, required=True)
    parser.add_argument("--topic", default="/octomap_binary")
    parser.add_argument("--first-stamp", type=int, default=1_700_000_000)
    parser.add_argument("--predicted-out", required=True)
    parser.add_argument("--timeout", type=float, default=60.0)
    parser.add_argument("maps", nargs="+")
    args = parser.parse_args()

    os.environ["CYCLONEDDS_URI"] = LOOPBACK_CONFIG
    from cyclonedds.core import Qos, Policy
    from cyclonedds.domain import DomainParticipant
    from cyclonedds.idl import IdlStruct
    from cyclonedds.idl.types import float64, int32, sequence, uint8, uint32
    import cyclonedds.idl.annotations as annotate
    from cyclonedds.pub import DataWriter
    from cyclonedds.sub import DataReader
    from cyclonedds.topic import Topic
    from cyclonedds.util import duration

    @dataclass
    @annotate.final
    class Time(IdlStruct, typename="builtin_interfaces::msg::dds_::Time_"):
        sec: int32
        nanosec: uint32

    @dataclass
    @annotate.final
    class Header(IdlStruct, typename="std_msgs::msg::dds_::Header_"):
        stamp: Time
        frame_id: str

    @dataclass
    @annotate.final
    class Octomap(IdlStruct, typename="octomap_msgs::msg::dds_::Octomap_"):
        header: Header
        binary: bool
        id: str
        resolution: float64
        data: sequence[uint8]

    latched = Qos(
        Policy.Reliability.Reliable(duration(seconds=1)),
        Policy.Durability.TransientLocal,
        Policy.History.KeepLast(max(len(args.maps), 1)),
        Policy.DataRepresentation(use_cdrv0_representation=True),
    )
    participant = DomainParticipant(args.domain)
    maps_topic = Topic(participant, "rt" + args.topic, Octomap)
    writer = DataWriter(participant, maps_topic, qos=latched)
    for i, path in enumerate(args.maps):
        if i == 1:
            # The first map is latched before the node exists; the others are published
            # live once the test says the node has it (a line on stdin).
            sys.stdin.readline()
        with open(path, "rb") as f:
            binary, tree_id, resolution, body = split_map_file(f.read())
        stamp = args.first_stamp + i
        writer.write(Octomap(Header(Time(stamp, 0), "map"), binary, tree_id, resolution, list(body)))
        say(event="published", map=path, stamp=stamp, binary=binary, bytes=len(body))

    predicted_topic = Topic(participant, "rt/froctomap/predicted", Octomap)
    reader = DataReader(participant, predicted_topic, qos=latched)
    deadline = time.monotonic() + args.timeout
    while time.monotonic() < deadline:
        samples = reader.take(N=1)
        if samples:
            message = samples[0]
            body = bytes(message.data)
            header = (
                "# Octomap OcTree binary file\n"
                f"id {message.id}\nsize {binary_node_count(body)}\n"
                f"res {message.resolution!r}\ndata\n"
            ).encode("ascii")
            with open(args.predicted_out, "wb") as f:
                f.write(header + body)
            say(event="predicted", stamp=message.header.stamp.sec, binary=message.binary,
                id=message.id, bytes=len(body))
            break
        time.sleep(0.05)
    else:
        say(event="timeout", waiting_for="rt/froctomap/predicted")
        sys.exit(2)
    # Stay until the test is done with the latched maps (it closes stdin).
    sys.stdin.read()


if __name__ == "__main__":
    main()
