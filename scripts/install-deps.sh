#!/usr/bin/env bash
# Installs the system packages froctomap needs, only those missing, on Debian/Ubuntu:
# the upstream OctoMap library and tools, a C++ compiler, pkg-config, and Python's venv.
set -euo pipefail

need=()
have_pkg() { dpkg-query -W -f='${Status}' "$1" 2>/dev/null | grep -q "install ok installed"; }
# liboctomap-dev/octomap-tools: the upstream library and tools; zstd, xz-utils and
# fonts-dejavu-core: the benchmark's archive baselines and plot labels.
for pkg in liboctomap-dev octomap-tools pkg-config g++ zstd xz-utils fonts-dejavu-core; do
  have_pkg "$pkg" || need+=("$pkg")
done
# The interoperability tests build a venv; Debian's python3 needs python3-venv for that.
if ! python3 -c 'import venv, ensurepip' >/dev/null 2>&1; then
  need+=(python3 python3-venv)
fi
[ ${#need[@]} -eq 0 ] && exit 0

if ! command -v apt-get >/dev/null; then
  echo "install-deps.sh: missing ${need[*]}, and this is not a Debian-like system; install them by hand" >&2
  exit 1
fi
sudo=()
if [ "$(id -u)" -ne 0 ]; then
  if command -v sudo >/dev/null; then sudo=(sudo); else
    echo "install-deps.sh: missing ${need[*]}; run as root or install sudo" >&2
    exit 1
  fi
fi
echo "install-deps.sh: installing ${need[*]}" >&2
export DEBIAN_FRONTEND=noninteractive
"${sudo[@]}" apt-get update -qq
"${sudo[@]}" apt-get install -y -qq --no-install-recommends "${need[@]}" >/dev/null
