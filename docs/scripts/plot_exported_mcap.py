"""Draws, top down, the foxglove.PointCloud messages of an MCAP file written by
`froctomap export --format mcap`, as read back by the PyPI `mcap` package: one panel per
chosen time, each point in the colour the file gives it. Only points between 0.1 m and 2 m
high are drawn (the floor and ceiling would hide everything else); dynamic voxels lie on top of
static ones, and lower probabilities on top of higher ones. A stand-in for a Foxglove
screenshot, which cannot be taken where the docs are built; it shows the same channel's data.

Usage: python plot_exported_mcap.py FILE.mcap OUT.png TIME_NS [TIME_NS…]
Needs only the `mcap` package (and the standard library: the PNG is written by hand).
"""
import base64
import json
import struct
import sys
import zlib

from mcap.reader import make_reader

SCALE = 2  # pixels per voxel
LOW_Z, HIGH_Z = 0.1, 2.0  # metres: the slice drawn
GAP = 12   # pixels between panels

path, out, wanted = sys.argv[1], sys.argv[2], [int(t) for t in sys.argv[3:]]
clouds = {}
with open(path, "rb") as f:
    for _, _, message in make_reader(f).iter_messages(topics=["/froctomap/occupied_voxels"]):
        if message.log_time in wanted:
            clouds[message.log_time] = json.loads(message.data)
missing = [t for t in wanted if t not in clouds]
if missing:
    sys.exit(f"no point cloud at {missing}")

panels, low, high = [], [10**9, 10**9], [-10**9, -10**9]
for t in wanted:
    cloud = clouds[t]
    fields = {f["name"]: f["offset"] for f in cloud["fields"]}
    value = next(n for n in fields if n not in ("x", "y", "z", "red", "green", "blue", "alpha"))
    data, stride = base64.b64decode(cloud["data"]), cloud["point_stride"]
    points = []
    for i in range(0, len(data), stride):
        x, y, z = struct.unpack_from("<fff", data, i + fields["x"])
        if not LOW_Z <= z <= HIGH_Z:
            continue
        colour = tuple(data[i + fields[c]] for c in ("red", "green", "blue"))
        v = struct.unpack_from("<f", data, i + fields[value])[0]
        points.append((-v if value == "p" else v, x, y, colour))
    points.sort()
    panels.append(points)
    for _, x, y, _ in points:
        low = [min(low[0], x), min(low[1], y)]
        high = [max(high[0], x), max(high[1], y)]

# The voxel size: the smallest spacing between distinct x coordinates of the first panel.
xs = sorted({round(p[1], 4) for p in panels[0]})
resolution = min((b - a for a, b in zip(xs, xs[1:]) if b - a > 1e-4), default=0.1)
width_voxels = int(round((high[0] - low[0]) / resolution)) + 1
height_voxels = int(round((high[1] - low[1]) / resolution)) + 1
pw, ph = width_voxels * SCALE, height_voxels * SCALE
width = len(panels) * pw + (len(panels) - 1) * GAP
image = [[(255, 255, 255)] * width for _ in range(ph)]
for k, points in enumerate(panels):
    left = k * (pw + GAP)
    for _, x, y, colour in points:
        col = left + int(round((x - low[0]) / resolution)) * SCALE
        row = (height_voxels - 1 - int(round((y - low[1]) / resolution))) * SCALE
        for dy in range(SCALE):
            image[row + dy][col:col + SCALE] = [colour] * SCALE

raw = b"".join(b"\0" + bytes(c for pixel in row for c in pixel) for row in image)


def chunk(kind, body):
    return struct.pack(">I", len(body)) + kind + body + struct.pack(">I", zlib.crc32(kind + body))


with open(out, "wb") as f:
    f.write(b"\x89PNG\r\n\x1a\n")
    f.write(chunk(b"IHDR", struct.pack(">IIBBBBB", width, ph, 8, 2, 0, 0, 0)))
    f.write(chunk(b"IDAT", zlib.compress(raw, 9)))
    f.write(chunk(b"IEND", b""))
print(f"{out}: {width}x{ph}, {[len(p) for p in panels]} points")
