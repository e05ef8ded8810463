#!/usr/bin/env bash
# Creates a Python venv with the PyPI package octomap-python (upstream OctoMap 1.10, linked
# statically): a second, separately built OctoMap client for interoperability tests; and
# rosbags, mcap and mcap-ros2-support, independent writers of ROS 1 bags, ROS 2 bags and MCAP
# files for the recording tests; cyclonedds (Eclipse Cyclone DDS, rmw_cyclonedds' DDS), the
# independent ROS 2 peer of the node's test (tests/scripts/ros2_peer.py); Foxglove's own
# message schemas (foxglove-schemas-protobuf), which exported Foxglove messages must parse as.
# Usage: scripts/python-client.sh VENV_DIR   (idempotent)
set -euo pipefail
venv=${1:?usage: python-client.sh VENV_DIR}
version=1.10.0.0
ros_packages=(rosbags==0.11.9 mcap==1.6.0 mcap-ros2-support==0.6.0 cyclonedds==11.0.1
              foxglove-schemas-protobuf==0.4.0)
check="import octomap, rosbags, mcap, mcap_ros2, cyclonedds.domain, foxglove_schemas_protobuf"
if "$venv/bin/python" -c "$check" 2>/dev/null; then
  exit 0
fi
python=$(command -v python3 || true)
if [ -z "$python" ]; then
  echo "python-client.sh: python3 is missing (install python3 and python3-venv)" >&2
  exit 1
fi
# Build in a sibling directory and rename, so concurrent test processes never see half a venv.
tmp="$venv.tmp.$$"
rm -rf "$tmp"
"$python" -m venv "$tmp"
"$tmp/bin/python" -m pip install --quiet --disable-pip-version-check "octomap-python==$version" "${ros_packages[@]}"
rm -rf "$venv"
mv "$tmp" "$venv"
# Paths inside a venv are absolute; re-create the launcher links for the final location.
"$python" -m venv --upgrade "$venv" >/dev/null
"$venv/bin/python" -c "$check" || { echo "python-client.sh: the Python packages did not import" >&2; exit 1; }
