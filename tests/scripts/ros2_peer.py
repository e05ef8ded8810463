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

Then it is a service client of the node, as rmw_cyclonedds is (`--service-mapping cyclone`:
requests on `rq/<service>Request` behind a 16-byte header, the client id (its request
writer's instance handle) and a sequence number, which the reply echoes; replies on
`rr/<service>Reply`, those of other clients skipped) or as DDS-RPC's basic mapping is
(`basic`: a RequestHeader, sample identity and instance name, before the request, a
ReplyHeader before the reply). It reads one JSON command a line from stdin until EOF:

  {"call": "get_octomap_at", "sec": S, "nanosec": N, "predict": B, "out": "map.bt"}
      -> {"event": "get_octomap_at", "success": B, "message": "...", "stamp": [S, N], ...}
         and, on success, the map written as a .bt file to "out" ("seconds": the call's
         round trip)
  {"call": "probability_at", "sec": S, "nanosec": N, "points": [[x, y, z], ...]}
      -> {"event": "probability_at", "p_bits": ["<f64 little-endian hex>", ...]}

  {"call": "get_parameters", "names": [N, ...]}
      -> {"event": "get_parameters", "values": [{"type": T, "bool": B, "integer": I,
         "double": D, "string": S}, ...]} (rcl_interfaces/srv/GetParameters)
  {"call": "list_parameters"}
      -> {"event": "list_parameters", "names": [...]} (rcl_interfaces/srv/ListParameters)
  {"call": "graph"}
      -> {"event": "graph", "entries": [{"gid": HEX, "nodes": [{"namespace", "name",
         "readers", "writers"}]}], "participants": [GUID HEX], "publications": {GUID HEX:
         topic}}: the ros_discovery_info entries (16-byte Gid) and what Cyclone discovered

The node's topics and services are looked for under --node (default /froctomap, the node
`froctomap` without a namespace); with --clock SEC the peer publishes rosgraph_msgs/Clock
at SEC on rt/clock while it waits for the predicted map.

and, to try the node with bad input (each answered by {"event": "published", ...}):

  {"call": "publish_map", "path": P, "stamp": S, "truncate": N?, "resolution": R?,
   "frame_id": F?}
      a map file on the map topic at stamp S (in frame F, default "map"), its body cut to N
      bytes or its resolution replaced when asked; the event says whether every matched reader acknowledged it
      ("acked")
  {"call": "publish_garbage", "size": N, "binary": B}
      an Octomap whose data is N bytes of noise
  {"call": "publish_wrong_type"}
      a message of another layout (a std_msgs/String) under the Octomap type name, from a
      second participant (one participant cannot hold both types of the topic)

With --no-predicted the peer does not wait for rt/froctomap/predicted. With --markers-out
M.json it then waits for the visualization_msgs/MarkerArray on rt/froctomap/dynamic (the
types declared here as ROS 2 Humble and later define them) and writes its markers to M.json.

Usage: ros2_peer.py --domain D --predicted-out OUT.bt [--topic /octomap_binary]
                    [--first-stamp SECONDS] [--timeout S] [--service-mapping M] MAP...
"""

import argparse
import json
import os
import struct
import sys
import time
import types
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


def read_markers(participant, qos, out, deadline, node):
    """Waits for one visualization_msgs/MarkerArray on rt/froctomap/dynamic, declared here
    as ROS 2 Humble and later define it, and writes its markers to `out` as JSON."""
    from cyclonedds.idl import IdlStruct
    from cyclonedds.idl.types import float32, float64, int32, sequence, uint8, uint32
    import cyclonedds.idl.annotations as annotate
    from cyclonedds.sub import DataReader
    from cyclonedds.topic import Topic

    def struct(typename, fields):
        body = lambda ns: ns.update({"__annotations__": fields})
        name = typename.rsplit("::", 1)[1]
        cls = types.new_class(name, (IdlStruct,), {"typename": typename}, body)
        return dataclass(annotate.final(cls))

    time_ = struct("builtin_interfaces::msg::dds_::Time_", {"sec": int32, "nanosec": uint32})
    header = struct("std_msgs::msg::dds_::Header_", {"stamp": time_, "frame_id": str})
    point = struct("geometry_msgs::msg::dds_::Point_", {"x": float64, "y": float64, "z": float64})
    quaternion = struct("geometry_msgs::msg::dds_::Quaternion_",
                        {"x": float64, "y": float64, "z": float64, "w": float64})
    pose = struct("geometry_msgs::msg::dds_::Pose_", {"position": point, "orientation": quaternion})
    vector3 = struct("geometry_msgs::msg::dds_::Vector3_", {"x": float64, "y": float64, "z": float64})
    color = struct("std_msgs::msg::dds_::ColorRGBA_",
                   {"r": float32, "g": float32, "b": float32, "a": float32})
    duration_ = struct("builtin_interfaces::msg::dds_::Duration_", {"sec": int32, "nanosec": uint32})
    image = struct("sensor_msgs::msg::dds_::CompressedImage_",
                   {"header": header, "format": str, "data": sequence[uint8]})
    uv = struct("visualization_msgs::msg::dds_::UVCoordinate_", {"u": float32, "v": float32})
    mesh = struct("visualization_msgs::msg::dds_::MeshFile_", {"filename": str, "data": sequence[uint8]})
    marker = struct("visualization_msgs::msg::dds_::Marker_", {
        "header": header, "ns": str, "id": int32, "type": int32, "action": int32, "pose": pose,
        "scale": vector3, "color": color, "lifetime": duration_, "frame_locked": bool,
        "points": sequence[point], "colors": sequence[color], "texture_resource": str,
        "texture": image, "uv_coordinates": sequence[uv], "text": str, "mesh_resource": str,
        "mesh_file": mesh, "mesh_use_embedded_materials": bool})
    marker_array = struct("visualization_msgs::msg::dds_::MarkerArray_", {"markers": sequence[marker]})
    reader = DataReader(participant, Topic(participant, f"rt{node}/dynamic", marker_array), qos=qos)
    while time.monotonic() < deadline:
        samples = reader.take(N=1)
        if samples:
            markers = [{
                "frame_id": m.header.frame_id, "stamp": [m.header.stamp.sec, m.header.stamp.nanosec],
                "ns": m.ns, "id": m.id, "type": m.type, "action": m.action,
                "pose": [m.pose.position.x, m.pose.position.y, m.pose.position.z,
                         m.pose.orientation.x, m.pose.orientation.y, m.pose.orientation.z,
                         m.pose.orientation.w],
                "scale": [m.scale.x, m.scale.y, m.scale.z],
                "points": [[p.x, p.y, p.z] for p in m.points],
                "colors": [[c.r, c.g, c.b, c.a] for c in m.colors],
                "rest": [m.texture_resource, m.texture.format, len(m.uv_coordinates), m.text,
                         m.mesh_resource, m.mesh_file.filename, m.mesh_use_embedded_materials],
            } for m in samples[0].markers]
            with open(out, "w") as f:
                json.dump(markers, f)
            say(event="markers", markers=len(markers))
            return
        time.sleep(0.05)
    say(event="timeout", waiting_for="rt/froctomap/dynamic")
    sys.exit(2)


def read_graph(participant, timeout):
    """The ROS graph entries on ros_discovery_info (rmw_dds_common/ParticipantEntitiesInfo
    with the 16-byte Gid of Iron and later, declared here) and what Cyclone DDS itself
    discovered: the participants' GUIDs and each publication's GUID and topic."""
    from cyclonedds.builtin import BuiltinDataReader, BuiltinTopicDcpsParticipant, BuiltinTopicDcpsPublication
    from cyclonedds.core import Qos, Policy
    from cyclonedds.idl import IdlStruct
    from cyclonedds.idl.types import array, sequence, uint8
    import cyclonedds.idl.annotations as annotate
    from cyclonedds.sub import DataReader
    from cyclonedds.topic import Topic
    from cyclonedds.util import duration

    @dataclass
    @annotate.final
    class Gid(IdlStruct, typename="rmw_dds_common::msg::dds_::Gid_"):
        data: array[uint8, 16]

    @dataclass
    @annotate.final
    class NodeEntitiesInfo(IdlStruct, typename="rmw_dds_common::msg::dds_::NodeEntitiesInfo_"):
        node_namespace: str
        node_name: str
        reader_gid_seq: sequence[Gid]
        writer_gid_seq: sequence[Gid]

    @dataclass
    @annotate.final
    class ParticipantEntitiesInfo(IdlStruct, typename="rmw_dds_common::msg::dds_::ParticipantEntitiesInfo_"):
        gid: Gid
        node_entities_info_seq: sequence[NodeEntitiesInfo]

    qos = Qos(Policy.Reliability.Reliable(duration(seconds=1)), Policy.Durability.TransientLocal,
              Policy.History.KeepLast(10), Policy.DataRepresentation(use_cdrv0_representation=True))
    reader = DataReader(participant, Topic(participant, "ros_discovery_info", ParticipantEntitiesInfo), qos=qos)
    participants = BuiltinDataReader(participant, BuiltinTopicDcpsParticipant)
    publications = BuiltinDataReader(participant, BuiltinTopicDcpsPublication)
    hexed = lambda gid: bytes(gid.data).hex()
    entries, guids, writers = [], set(), {}
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline and not entries:
        for info in reader.take(N=16):
            entries.append({"gid": hexed(info.gid), "nodes": [
                {"namespace": n.node_namespace, "name": n.node_name,
                 "readers": [hexed(g) for g in n.reader_gid_seq],
                 "writers": [hexed(g) for g in n.writer_gid_seq]}
                for n in info.node_entities_info_seq]})
        time.sleep(0.05)
    time.sleep(0.5)
    for sample in participants.take(N=64):
        guids.add(sample.key.bytes.hex())
    for sample in publications.take(N=256):
        writers[sample.key.bytes.hex()] = sample.topic_name
    return {"entries": entries, "participants": sorted(guids), "publications": writers}


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--domain", type=int, required=True)
    parser.add_argument("--topic", default="/octomap_binary")
    parser.add_argument("--first-stamp", type=int, default=1_700_000_000)
    parser.add_argument("--predicted-out", required=True)
    parser.add_argument("--timeout", type=float, default=60.0)
    parser.add_argument("--service-mapping", choices=["cyclone", "basic"], default="cyclone")
    parser.add_argument("--no-predicted", action="store_true")
    parser.add_argument("--markers-out")
    parser.add_argument("--node", default="/froctomap",
                        help="the node's fully qualified name: its topics and services are under it")
    parser.add_argument("--clock", type=int,
                        help="publish rosgraph_msgs/Clock at this second on rt/clock while waiting")
    parser.add_argument("maps", nargs="+")
    args = parser.parse_args()

    os.environ["CYCLONEDDS_URI"] = LOOPBACK_CONFIG
    from cyclonedds.core import Qos, Policy
    from cyclonedds.domain import DomainParticipant
    from cyclonedds.idl import IdlStruct
    from cyclonedds.idl.types import array, float64, int32, int64, sequence, uint8, uint32, uint64
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
            # Written once the node's reader is matched, so that it gets every map, not
            # only the last one kept for late joiners.
            matched_by = time.monotonic() + args.timeout
            while (writer.get_publication_matched_status().current_count == 0
                   and time.monotonic() < matched_by):
                time.sleep(0.05)
        with open(path, "rb") as f:
            binary, tree_id, resolution, body = split_map_file(f.read())
        stamp = args.first_stamp + i
        writer.write(Octomap(Header(Time(stamp, 0), "map"), binary, tree_id, resolution, list(body)))
        say(event="published", map=path, stamp=stamp, binary=binary, bytes=len(body), wall=time.time())

    predicted_topic = Topic(participant, f"rt{args.node}/predicted", Octomap)
    clock_writer = None
    if args.clock is not None:
        @dataclass
        @annotate.final
        class Clock(IdlStruct, typename="rosgraph_msgs::msg::dds_::Clock_"):
            clock: Time

        clock_qos = Qos(Policy.Reliability.BestEffort, Policy.Durability.Volatile,
                        Policy.History.KeepLast(1), Policy.DataRepresentation(use_cdrv0_representation=True))
        clock_writer = DataWriter(participant, Topic(participant, "rt/clock", Clock), qos=clock_qos)
    reader = DataReader(participant, predicted_topic, qos=latched)
    deadline = time.monotonic() + args.timeout
    while not args.no_predicted and time.monotonic() < deadline:
        if clock_writer is not None:
            clock_writer.write(Clock(Time(args.clock, 0)))
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
            if args.markers_out:
                read_markers(participant, latched, args.markers_out, deadline, args.node)
            break
        time.sleep(0.05)
    else:
        if not args.no_predicted:
            say(event="timeout", waiting_for="rt/froctomap/predicted")
            sys.exit(2)
    # The services (froctomap_msgs/srv), framed as the chosen mapping frames them.
    @dataclass
    @annotate.final
    class Point(IdlStruct, typename="geometry_msgs::msg::dds_::Point_"):
        x: float64
        y: float64
        z: float64

    @dataclass
    @annotate.final
    class SampleIdentity(IdlStruct, typename="dds::rpc::SampleIdentity"):
        guid: array[uint8, 16]
        sequence_high: int32
        sequence_low: uint32

    stem = "froctomap_msgs::srv::dds_::"

    def idl_struct(name, fields, prefix=stem):
        # types.new_class hands `typename` to IdlStruct's metaclass, as a class statement does.
        body = lambda ns: ns.update({"__annotations__": fields})
        cls = types.new_class(name, (IdlStruct,), {"typename": prefix + name}, body)
        return dataclass(annotate.final(cls))

    if args.service_mapping == "cyclone":
        # rmw_cyclonedds' cdds_request_header_t: uint64 guid, int64 seq.
        def framed(name, fields, prefix=stem):
            annotations = {"client": uint64, "sequence": int64, **fields}
            return idl_struct(name, annotations, prefix)
        request_header = lambda handle, seq: {"client": handle, "sequence": seq}
    else:
        def framed(name, fields, prefix=stem):
            header = ({"identity": SampleIdentity, "instance_name": str} if name.endswith("Request_")
                      else {"identity": SampleIdentity, "remote_exception": uint32})
            return idl_struct(name, {**header, **fields}, prefix)
        def request_header(handle, seq):
            guid = list(writer_guids[handle])
            return {"identity": SampleIdentity(guid, seq >> 32, seq & 0xFFFFFFFF), "instance_name": ""}

    @dataclass
    @annotate.final
    class ParameterValue(IdlStruct, typename="rcl_interfaces::msg::dds_::ParameterValue_"):
        type: uint8
        bool_value: bool
        integer_value: int64
        double_value: float64
        string_value: str
        byte_array_value: sequence[uint8]
        bool_array_value: sequence[bool]
        integer_array_value: sequence[int64]
        double_array_value: sequence[float64]
        string_array_value: sequence[str]

    service_types = {
        "get_octomap_at": (framed("GetOctomapAt_Request_", {"stamp": Time, "predict": bool}),
                           framed("GetOctomapAt_Response_", {"success": bool, "message": str, "map": Octomap})),
        "probability_at": (framed("ProbabilityAt_Request_", {"stamp": Time, "points": sequence[Point]}),
                           framed("ProbabilityAt_Response_", {"p": sequence[float64]})),
    }
    rcl_stem = "rcl_interfaces::srv::dds_::"
    parameter_types = {
        "list_parameters": (
            framed("ListParameters_Request_", {"prefixes": sequence[str], "depth": uint64}, rcl_stem),
            framed("ListParameters_Response_", {"names": sequence[str], "prefixes": sequence[str]}, rcl_stem)),
        "get_parameters": (
            framed("GetParameters_Request_", {"names": sequence[str]}, rcl_stem),
            framed("GetParameters_Response_", {"values": sequence[ParameterValue]}, rcl_stem)),
    }
    service_qos = Qos(
        Policy.Reliability.Reliable(duration(seconds=1)),
        Policy.Durability.Volatile,
        Policy.History.KeepAll,
        Policy.DataRepresentation(use_cdrv0_representation=True),
    )
    clients = {}
    writer_guids = {}
    for name, (request_type, reply_type) in {**service_types, **parameter_types}.items():
        request_writer = DataWriter(participant, Topic(participant, f"rq{args.node}/{name}Request", request_type),
                                    qos=service_qos)
        reply_reader = DataReader(participant, Topic(participant, f"rr{args.node}/{name}Reply", reply_type),
                                  qos=service_qos)
        writer_guids[request_writer.instance_handle & 0xFFFF_FFFF_FFFF_FFFF] = request_writer.guid.bytes
        clients[name] = (request_type, request_writer, reply_reader)

    def own_id(reply, handle, seq):
        if args.service_mapping == "cyclone":
            return reply.client == handle and reply.sequence == seq
        identity = reply.identity
        return (bytes(identity.guid) == writer_guids[handle]
                and (identity.sequence_high << 32 | identity.sequence_low) == seq)

    next_sequence = 0
    keep_alive = []

    def call(name, fields):
        nonlocal next_sequence
        request_type, request_writer, reply_reader = clients[name]
        deadline = time.monotonic() + args.timeout / 2
        # The node's request reader and reply writer must be matched first (volatile QoS).
        while not (request_writer.get_matched_subscriptions() and reply_reader.get_matched_publications()):
            if time.monotonic() > deadline:
                say(event="timeout", waiting_for=f"the node's {name} service",
                    matched=[len(request_writer.get_matched_subscriptions()),
                             len(reply_reader.get_matched_publications())])
                sys.exit(2)
            time.sleep(0.05)
        next_sequence += 1
        handle = request_writer.instance_handle & 0xFFFF_FFFF_FFFF_FFFF  # a uint64, as rmw keeps it
        request_writer.write(request_type(**request_header(handle, next_sequence), **fields))
        while time.monotonic() < deadline:
            for reply in reply_reader.take(N=16):
                if own_id(reply, handle, next_sequence):
                    return reply
            time.sleep(0.02)
        say(event="timeout", waiting_for=f"the reply of {name}")
        sys.exit(2)

    for line in sys.stdin:
        if not line.strip():
            continue
        command = json.loads(line)
        if "sec" in command:
            stamp = Time(command["sec"], command["nanosec"])
        if command["call"] == "get_octomap_at":
            called = time.monotonic()
            reply = call("get_octomap_at", {"stamp": stamp, "predict": command["predict"]})
            seconds = time.monotonic() - called
            body = bytes(reply.map.data)
            if reply.success:
                header = (
                    "# Octomap OcTree binary file\n"
                    f"id {reply.map.id}\nsize {binary_node_count(body)}\n"
                    f"res {reply.map.resolution!r}\ndata\n"
                ).encode("ascii")
                with open(command["out"], "wb") as f:
                    f.write(header + body)
            say(event="get_octomap_at", success=reply.success, message=reply.message,
                stamp=[reply.map.header.stamp.sec, reply.map.header.stamp.nanosec],
                frame_id=reply.map.header.frame_id, binary=reply.map.binary, bytes=len(body),
                seconds=seconds)
        elif command["call"] == "probability_at":
            points = [Point(*p) for p in command["points"]]
            reply = call("probability_at", {"stamp": stamp, "points": points})
            say(event="probability_at", p_bits=[struct.pack("<d", p).hex() for p in reply.p])
        elif command["call"] == "get_parameters":
            reply = call("get_parameters", {"names": command["names"]})
            say(event="get_parameters", values=[
                {"type": v.type, "bool": v.bool_value, "integer": v.integer_value,
                 "double": v.double_value, "string": v.string_value} for v in reply.values])
        elif command["call"] == "graph":
            say(event="graph", **read_graph(participant, args.timeout / 2))
        elif command["call"] == "list_parameters":
            reply = call("list_parameters", {"prefixes": [], "depth": 0})
            say(event="list_parameters", names=list(reply.names))
        elif command["call"] == "publish_map":
            with open(command["path"], "rb") as f:
                binary, tree_id, resolution, body = split_map_file(f.read())
            body = body[: command.get("truncate", len(body))]
            # A reader matched first: a sample written before would only reach it as the one
            # kept (keep-last), and wait_for_acks holds for no reader at all.
            matched_by = time.monotonic() + args.timeout
            while (writer.get_publication_matched_status().current_count == 0
                   and time.monotonic() < matched_by):
                time.sleep(0.05)
            resolution = command.get("resolution", resolution)
            writer.write(Octomap(Header(Time(command["stamp"], 0), command.get("frame_id", "map")), binary,
                                 tree_id, resolution, list(body)))
            # Acknowledged by every matched reader: the node's DDS reader holds it.
            acked = writer.wait_for_acks(duration(seconds=10))
            say(event="published", map=command["path"], stamp=command["stamp"], bytes=len(body),
                acked=acked, wall=time.time())
        elif command["call"] == "publish_garbage":
            noise = bytes((i * 7919 + 13) % 251 for i in range(command["size"]))
            writer.write(Octomap(Header(Time(command["stamp"], 0), "map"), command["binary"], "OcTree", 0.1,
                                 list(noise)))
            say(event="published", garbage=command["size"])
        elif command["call"] == "publish_wrong_type":
            @dataclass
            @annotate.final
            class NotAMap(IdlStruct, typename="octomap_msgs::msg::dds_::Octomap_"):
                data: str

            other = DomainParticipant(args.domain)
            wrong = DataWriter(other, Topic(other, "rt" + args.topic, NotAMap), qos=latched)
            wrong.write(NotAMap("this is a std_msgs/String, not a map"))
            keep_alive.append((other, wrong))
            say(event="published", wrong_type=True)
        else:
            say(event="error", unknown=command["call"])


if __name__ == "__main__":
    main()
