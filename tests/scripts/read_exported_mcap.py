"""Reads an MCAP file exported by froctomap with independent readers (PyPI mcap and
mcap-ros2-support) and reports what it holds, for the recording tests.

Usage: python read_exported_mcap.py FILE.mcap OUT_DIR [BT_FILES.json]
Writes OUT_DIR/<log_time>.data (each octomap message's decoded `data` field) and prints one
JSON object: the header profile, the schemas and channels, each octomap message's fields,
each point-cloud message's point count, distinct colours and value range, and for each
sensor_msgs/PointCloud2 message (decoded by mcap-ros2-support through its embedded schema)
whether its points, colours and values are those of the point cloud of the same time. BT_FILES.json maps
log times to .bt files (the .bt export of the same times): each cloud's points are then
compared with the occupied voxels octomap-python reads from that file ("same_voxels").
"""
import base64
import json
import os
import struct
import sys

from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory



def occupied_voxels(bt, resolution):
    """The integer keys (x, y, z) of every occupied voxel of a .bt file, per octomap-python."""
    import octomap
    tree = octomap.OcTree(bt.encode())
    keys = set()
    it = tree.begin_leafs()
    for leaf in it:
        if not tree.isNodeOccupied(leaf):
            continue
        n = round(leaf.getSize() / resolution)
        low = [round((c - leaf.getSize() / 2) / resolution) for c in leaf.getCoordinate()]
        for i in range(n):
            for j in range(n):
                for k in range(n):
                    keys.add((low[0] + i, low[1] + j, low[2] + k))
    return keys


path, out_dir = sys.argv[1], sys.argv[2]
bt_files = json.load(open(sys.argv[3])) if len(sys.argv) > 3 else {}
report = {"octomap": [], "cloud": []}
with open(path, "rb") as f:
    reader = make_reader(f, decoder_factories=[DecoderFactory()])
    report["profile"] = reader.get_header().profile
    summary = reader.get_summary()
    report["schemas"] = {s.name: s.encoding for s in summary.schemas.values()}
    report["channels"] = {
        c.topic: {"encoding": c.message_encoding, "schema": summary.schemas[c.schema_id].name}
        for c in summary.channels.values()
    }
    for _, _, message, decoded in reader.iter_decoded_messages(topics=["/octomap_binary"]):
        data = bytes(b & 0xFF for b in decoded.data)
        with open(os.path.join(out_dir, f"{message.log_time}.data"), "wb") as out:
            out.write(data)
        stamp = decoded.header.stamp
        report["octomap"].append({
            "log_time": message.log_time,
            "stamp_ns": stamp.sec * 1_000_000_000 + stamp.nanosec,
            "frame_id": decoded.header.frame_id,
            "binary": decoded.binary,
            "id": decoded.id,
            "resolution": decoded.resolution,
        })
    f.seek(0)
    reader = make_reader(f)
    for _, _, message in reader.iter_messages(topics=["/froctomap/occupied_voxels"]):
        cloud = json.loads(message.data)
        data = base64.b64decode(cloud["data"])
        stride = cloud["point_stride"]
        fields = {field["name"]: (field["offset"], field["type"]) for field in cloud["fields"]}
        value_name = next(name for name in fields if name not in ("x", "y", "z", "red", "green", "blue", "alpha"))
        colours, values, keys, full = set(), [], [], set()
        resolution = report["octomap"][0]["resolution"] if report["octomap"] else 1.0
        for i in range(0, len(data), stride):
            point = data[i:i + stride]
            centre = [struct.unpack_from("<f", point, fields[c][0])[0] for c in ("x", "y", "z")]
            keys.append(tuple(int(c // resolution) for c in centre))
            colours.add(tuple(point[fields[c][0]] for c in ("red", "green", "blue", "alpha")))
            values.append(struct.unpack_from("<f", point, fields[value_name][0])[0])
            full.add((keys[-1], tuple(point[fields[c][0]] for c in ("red", "green", "blue", "alpha")), values[-1]))
        report["cloud"].append({
            "log_time": message.log_time,
            "stamp_ns": cloud["timestamp"]["sec"] * 1_000_000_000 + cloud["timestamp"]["nsec"],
            "frame_id": cloud["frame_id"],
            "points": len(data) // stride,
            "remainder": len(data) % stride,
            "value": value_name,
            "min": min(values, default=None),
            "max": max(values, default=None),
            "colours": len(colours),
            "distinct_points": len(set(keys)),
            "_points": full,
        })
        bt = bt_files.get(str(message.log_time))
        if bt is not None:
            report["cloud"][-1]["same_voxels"] = occupied_voxels(bt, resolution) == set(keys)
    # The PointCloud2 channel: the same points as the foxglove cloud of the same time.
    f.seek(0)
    reader = make_reader(f, decoder_factories=[DecoderFactory()])
    clouds = {c["log_time"]: c for c in report["cloud"]}
    report["cloud2"] = []
    for _, _, message, decoded in reader.iter_decoded_messages(topics=["/froctomap/occupied_voxels_pc2"]):
        data = bytes(decoded.data)
        fields = {field.name: (field.offset, field.datatype) for field in decoded.fields}
        value_name = next(name for name in fields if name not in ("x", "y", "z", "rgba"))
        resolution = report["octomap"][0]["resolution"] if report["octomap"] else 1.0
        points = set()
        for i in range(0, len(data), decoded.point_step):
            point = data[i:i + decoded.point_step]
            centre = [struct.unpack_from("<f", point, fields[c][0])[0] for c in ("x", "y", "z")]
            argb = struct.unpack_from("<I", point, fields["rgba"][0])[0]
            rgba = ((argb >> 16) & 0xFF, (argb >> 8) & 0xFF, argb & 0xFF, argb >> 24)
            value = struct.unpack_from("<f", point, fields[value_name][0])[0]
            points.add((tuple(int(c // resolution) for c in centre), rgba, value))
        stamp = decoded.header.stamp
        report["cloud2"].append({
            "log_time": message.log_time,
            "stamp_ns": stamp.sec * 1_000_000_000 + stamp.nanosec,
            "frame_id": decoded.header.frame_id,
            "points": decoded.width * decoded.height,
            "types": [fields[c][1] for c in ("x", "y", "z", "rgba", value_name)],
            "value": value_name,
            "same_points": points == clouds[message.log_time].pop("_points"),
        })
    for cloud in report["cloud"]:
        cloud.pop("_points", None)
print(json.dumps(report))
