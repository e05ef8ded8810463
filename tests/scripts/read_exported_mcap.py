"""Reads an MCAP file exported by froctomap with independent readers (PyPI mcap and
mcap-ros2-support) and reports what it holds, for the recording tests.

Usage: python read_exported_mcap.py FILE.mcap OUT_DIR [BT_FILES.json]
Every CDR message of the whole file is decoded by mcap-ros2-support's DecoderFactory through
its embedded ros2msg schema (`iter_decoded_messages()` without a topic filter when the file
has only CDR channels: a channel it cannot decode raises DecoderNotFoundError); JSON channels
(profile foxglove) are parsed and checked against Foxglove's own schemas (PyPI
foxglove-schemas-protobuf, each message parsed strictly with protobuf's JSON parser).
Writes OUT_DIR/<log_time>.data (each octomap message's decoded `data` field) and prints one
JSON object: the header profile, the schemas and channels, the message count per topic, each
octomap message's fields, and per message of the point clouds, markers and scene updates its
stamp, frame, point or cube count, value range and colours. BT_FILES.json maps log times to
.bt files (the .bt export of the same times): the occupied voxels of each cloud, marker array
and scene update are then compared with those octomap-python reads from that file
("same_voxels").
"""
import base64
import collections
import json
import os
import struct
import sys

from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory


def foxglove_problems(body, schema):
    """What Foxglove's own schema (the message of PyPI foxglove-schemas-protobuf named
    `schema`) refuses in a JSON message: parsed strictly (no unknown field, every value of its
    field's type) after the one difference of Foxglove's JSON encoding from protobuf's, times
    as {"sec", "nsec"} objects."""
    from google.protobuf import json_format
    from google.protobuf.duration_pb2 import Duration
    from google.protobuf.timestamp_pb2 import Timestamp
    import foxglove_schemas_protobuf
    import importlib

    name = schema.split(".")[-1]
    module = importlib.import_module(f"foxglove_schemas_protobuf.{name}_pb2")
    cls = getattr(module, name)
    times = {"google.protobuf.Timestamp": Timestamp, "google.protobuf.Duration": Duration}

    def convert(value, descriptor):
        if not isinstance(value, dict):
            return value
        out = {}
        for key, item in value.items():
            field = descriptor.fields_by_name.get(key)
            kind = field.message_type if field is not None else None
            if kind is None:
                out[key] = item
                continue
            def one(v):
                if kind.full_name in times and isinstance(v, dict) and set(v) == {"sec", "nsec"}:
                    t = times[kind.full_name](seconds=v["sec"], nanos=v["nsec"])
                    return t.ToJsonString()
                return convert(v, kind)
            out[key] = [one(v) for v in item] if isinstance(item, list) else one(item)
        return out

    try:
        message = json_format.Parse(json.dumps(convert(body, cls.DESCRIPTOR)), cls(),
                                    ignore_unknown_fields=False)
    except json_format.ParseError as error:
        return [f"{schema}: {error}"]
    # The parse kept what matters: the cubes or the points are there.
    if name == "SceneUpdate" and len(message.entities[0].cubes) != len(body["entities"][0]["cubes"]):
        return [f"{schema}: cubes lost in parsing"]
    if name == "PointCloud" and len(message.data) != len(base64.b64decode(body["data"])):
        return [f"{schema}: data lost in parsing"]
    return []


def occupied_voxels(bt, resolution):
    """The integer keys (x, y, z) of every occupied voxel of a .bt file, per octomap-python."""
    import octomap
    tree = octomap.OcTree(bt.encode())
    keys = set()
    for leaf in tree.begin_leafs():
        if tree.isNodeOccupied(leaf):
            keys |= box_voxels(leaf.getCoordinate(), leaf.getSize(), resolution)
    return keys


def box_voxels(centre, size, resolution):
    """The keys of the voxels a cube of edge `size` centred on `centre` covers."""
    n = round(size / resolution)
    low = [round((c - size / 2) / resolution) for c in centre]
    return {(low[0] + i, low[1] + j, low[2] + k) for i in range(n) for j in range(n) for k in range(n)}


# The structure of Foxglove's foxglove.SceneUpdate (docs.foxglove.dev, schemas/jsonschema):
# per object its fields' JSON types, the required ones marked "!".
VECTOR3 = {"x!": "number", "y!": "number", "z!": "number"}
QUATERNION = {"x!": "number", "y!": "number", "z!": "number", "w!": "number"}
COLOR = {"r!": "number", "g!": "number", "b!": "number", "a!": "number"}
TIME = {"sec": "integer", "nsec": "integer"}
CUBE = {"pose!": {"position!": VECTOR3, "orientation!": QUATERNION}, "size!": VECTOR3, "color!": COLOR}
ENTITY = {
    "timestamp!": TIME, "frame_id!": "string", "id!": "string", "lifetime!": TIME,
    "frame_locked!": "boolean", "metadata!": [{"key!": "string", "value!": "string"}],
    "arrows!": [dict], "cubes!": [CUBE], "spheres!": [dict], "cylinders!": [dict], "lines!": [dict],
    "triangles!": [dict], "texts!": [dict], "models!": [dict],
}
SCENE_UPDATE = {"deletions": [dict], "entities": [ENTITY]}
JSON_TYPES = {"number": (int, float), "integer": int, "string": str, "boolean": bool}


def conforms(value, spec, where="$"):
    """Problems of `value` against `spec` (a list of strings, empty when it conforms)."""
    if spec is dict:
        return [] if isinstance(value, dict) else [f"{where}: not an object"]
    if isinstance(spec, str):
        ok = isinstance(value, JSON_TYPES[spec]) and not (spec != "boolean" and isinstance(value, bool))
        return [] if ok else [f"{where}: not a {spec}"]
    if isinstance(spec, list):
        if not isinstance(value, list):
            return [f"{where}: not an array"]
        return [p for i, item in enumerate(value) for p in conforms(item, spec[0], f"{where}[{i}]")]
    if not isinstance(value, dict):
        return [f"{where}: not an object"]
    problems = []
    for key, field in spec.items():
        name = key.rstrip("!")
        if name in value:
            problems += conforms(value[name], field, f"{where}.{name}")
        elif key.endswith("!"):
            problems.append(f"{where}: no {name}")
    return problems


def stamp_ns(header):
    return header.stamp.sec * 1_000_000_000 + header.stamp.nanosec


path, out_dir = sys.argv[1], sys.argv[2]
bt_files = json.load(open(sys.argv[3])) if len(sys.argv) > 3 else {}
voxels_of = {}


def same_voxels(log_time, keys, resolution):
    bt = bt_files.get(str(log_time))
    if bt is None:
        return None
    if log_time not in voxels_of:
        voxels_of[log_time] = occupied_voxels(bt, resolution)
    return voxels_of[log_time] == keys


report = {"octomap": [], "cloud2": [], "markers": [], "cloud": [], "scene": []}
with open(path, "rb") as f:
    reader = make_reader(f, decoder_factories=[DecoderFactory()])
    report["profile"] = reader.get_header().profile
    summary = reader.get_summary()
    report["schemas"] = {s.name: s.encoding for s in summary.schemas.values()}
    report["channels"] = {
        c.topic: {"encoding": c.message_encoding, "schema": summary.schemas[c.schema_id].name}
        for c in summary.channels.values()
    }
    report["metadata"] = [{"name": m.name, **m.metadata} for m in reader.iter_metadata()]
    cdr_topics = [c.topic for c in summary.channels.values() if c.message_encoding == "cdr"]
    only_cdr = len(cdr_topics) == len(summary.channels)
    counts = collections.Counter()
    f.seek(0)
    reader = make_reader(f, decoder_factories=[DecoderFactory()])
    # The whole file when it is CDR only: a message that does not decode stops the test.
    decoded_messages = reader.iter_decoded_messages() if only_cdr else reader.iter_decoded_messages(topics=cdr_topics)
    resolution = None
    for _, channel, message, decoded in decoded_messages:
        counts[channel.topic] += 1
        schema = report["channels"][channel.topic]["schema"]
        if schema == "octomap_msgs/msg/Octomap":
            resolution = decoded.resolution
            data = bytes(b & 0xFF for b in decoded.data)
            with open(os.path.join(out_dir, f"{message.log_time}.data"), "wb") as out:
                out.write(data)
            report["octomap"].append({
                "topic": channel.topic,
                "log_time": message.log_time,
                "stamp_ns": stamp_ns(decoded.header),
                "frame_id": decoded.header.frame_id,
                "binary": decoded.binary,
                "id": decoded.id,
                "resolution": decoded.resolution,
            })
        elif schema == "sensor_msgs/msg/PointCloud2":
            data = bytes(decoded.data)
            fields = {field.name: (field.offset, field.datatype) for field in decoded.fields}
            keys, colours, values = set(), set(), collections.defaultdict(list)
            for i in range(0, len(data), decoded.point_step):
                point = data[i:i + decoded.point_step]
                centre = [struct.unpack_from("<f", point, fields[c][0])[0] for c in "xyz"]
                keys.add(tuple(int(c // resolution) for c in centre))
                colours.add(struct.unpack_from("<I", point, fields["rgba"][0])[0])
                for name in fields:
                    if name not in ("x", "y", "z", "rgba"):
                        values[name].append(struct.unpack_from("<f", point, fields[name][0])[0])
            report["cloud2"].append({
                "topic": channel.topic,
                "log_time": message.log_time,
                "stamp_ns": stamp_ns(decoded.header),
                "frame_id": decoded.header.frame_id,
                "points": decoded.width * decoded.height,
                "distinct_points": len(keys),
                "fields": [[field.name, field.datatype] for field in decoded.fields],
                "values": {n: [min(v), max(v)] if v and all(x == x for x in v) else ("nan" if v else None)
                           for n, v in values.items()},
                "colours": len(colours),
                "same_voxels": same_voxels(message.log_time, keys, resolution),
            })
        elif schema == "visualization_msgs/msg/MarkerArray":
            keys, cubes, problems = set(), 0, []
            for marker in decoded.markers:
                depth = marker.id
                size = resolution * 2 ** (16 - depth)
                if marker.type != 6:
                    problems.append(f"marker {depth}: type {marker.type}")
                if abs(marker.scale.x - size) > 1e-9 or marker.scale.x != marker.scale.z:
                    problems.append(f"marker {depth}: scale {marker.scale.x}")
                if len(marker.colors) != len(marker.points):
                    problems.append(f"marker {depth}: colours")
                if (marker.action == 0) != bool(marker.points):
                    problems.append(f"marker {depth}: action {marker.action}")
                for p in marker.points:
                    cubes += 1
                    keys |= box_voxels((p.x, p.y, p.z), size, resolution)
            report["markers"].append({
                "topic": channel.topic,
                "log_time": message.log_time,
                "stamp_ns": stamp_ns(decoded.markers[0].header),
                "frame_id": decoded.markers[0].header.frame_id,
                "markers": len(decoded.markers),
                "cubes": cubes,
                "problems": problems,
                "same_voxels": same_voxels(message.log_time, keys, resolution),
            })
    # JSON channels (profile foxglove): parsed, checked against Foxglove's schemas.
    f.seek(0)
    reader = make_reader(f)
    json_topics = [c.topic for c in summary.channels.values() if c.message_encoding == "json"]
    for _, channel, message in reader.iter_messages(topics=json_topics):
        counts[channel.topic] += 1
        body = json.loads(message.data)
        schema = report["channels"][channel.topic]["schema"]
        if schema == "foxglove.PointCloud":
            data = base64.b64decode(body["data"])
            stride = body["point_stride"]
            fields = {field["name"]: field["offset"] for field in body["fields"]}
            keys = {tuple(int(struct.unpack_from("<f", data, i + fields[c])[0] // resolution) for c in "xyz")
                    for i in range(0, len(data), stride)}
            report["cloud"].append({
                "log_time": message.log_time,
                "frame_id": body["frame_id"],
                "points": len(data) // stride,
                "remainder": len(data) % stride,
                "fields": sorted(fields),
                "problems": foxglove_problems(body, schema),
                "same_voxels": same_voxels(message.log_time, keys, resolution),
            })
        elif schema == "foxglove.SceneUpdate":
            problems = conforms(body, SCENE_UPDATE) + foxglove_problems(body, schema)
            keys, sizes = set(), set()
            entity = body["entities"][0]
            for cube in entity["cubes"]:
                p, s = cube["pose"]["position"], cube["size"]
                sizes.add(round(s["x"] / resolution))
                keys |= box_voxels((p["x"], p["y"], p["z"]), s["x"], resolution)
            report["scene"].append({
                "log_time": message.log_time,
                "stamp_ns": entity["timestamp"]["sec"] * 1_000_000_000 + entity["timestamp"]["nsec"],
                "frame_id": entity["frame_id"],
                "entities": len(body["entities"]),
                "cubes": len(entity["cubes"]),
                "sizes": sorted(sizes),
                "metadata": {kv["key"]: kv["value"] for kv in entity["metadata"]},
                "problems": problems,
                "same_voxels": same_voxels(message.log_time, keys, resolution),
            })
    report["counts"] = dict(counts)
print(json.dumps(report))
