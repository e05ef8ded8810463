"""Checks the froctomap node's CDR encoding of its service messages against the PyPI
`rosbags` type system, which reads the `.srv` files of ros/froctomap_msgs itself.

Each `.srv` is split at its `---` line into `<pkg>/srv/<Name>_Request` and `_Response`, as
rosidl does, and registered with rosbags next to `octomap_msgs/msg/Octomap` (its definition
as octomap_msgs ships it) and the ROS 2 Humble standard types. For every case of the JSON
file given (a list of {"type", "cdr_hex", "fields"}), the node's bytes must deserialize to
`fields` and rosbags must serialize that message back to the same bytes.

Prints one JSON line: {"checked": N} or {"error": "..."}.

Usage: srv_cdr.py SRV_DIR CASES.json
"""

import json
import struct
import sys
from pathlib import Path

OCTOMAP_MSG = """std_msgs/Header header
bool binary
string id
float64 resolution
int8[] data
"""


def plain(value):
    """A rosbags message as JSON-comparable data (floats as their bits, arrays as lists)."""
    if hasattr(value, "__dataclass_fields__"):
        return {name: plain(getattr(value, name)) for name in value.__dataclass_fields__
                if name != "__msgtype__"}
    if hasattr(value, "tolist"):
        value = value.tolist()
    if isinstance(value, bytes):
        value = list(value)
    if isinstance(value, list):
        return [plain(item) for item in value]
    if isinstance(value, float):
        return struct.pack("<d", value).hex()
    return value


def main():
    from rosbags.typesys import Stores, get_typestore, get_types_from_msg

    srv_dir, cases_path = Path(sys.argv[1]), Path(sys.argv[2])
    typestore = get_typestore(Stores.ROS2_HUMBLE)
    types = get_types_from_msg(OCTOMAP_MSG, "octomap_msgs/msg/Octomap")
    # rosbags files every definition under a `msg` namespace (`pkg/srv/msg/Name`).
    names = {}
    for srv in sorted(srv_dir.glob("*.srv")):
        request, response = srv.read_text().split("\n---\n")
        for half, text in (("Request", request), ("Response", response)):
            name = f"froctomap_msgs/srv/{srv.stem}_{half}"
            found = get_types_from_msg(text, name)
            names[name] = next(iter(found))
            types.update(found)
    typestore.register(types)

    cases = json.loads(cases_path.read_text())
    for case in cases:
        ours = bytes.fromhex(case["cdr_hex"])
        typename = names[case["type"]]
        message = typestore.deserialize_cdr(ours, typename)
        got = plain(message)
        if got != case["fields"]:
            print(json.dumps({"error": f"{case['type']}: rosbags reads {got}, not {case['fields']}"}))
            return
        again = bytes(typestore.serialize_cdr(message, typename))
        if again != ours:
            print(json.dumps({"error": f"{case['type']}: rosbags writes {again.hex()}, the node {ours.hex()}"}))
            return
    print(json.dumps({"checked": len(cases)}))


if __name__ == "__main__":
    main()
