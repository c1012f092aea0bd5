#!/usr/bin/env bash
# Installs the system pieces echo-data needs on Debian bookworm (run as root):
# Mesa >= 23 lavapipe from bookworm-backports (bookworm's own 22.3 lacks
# descriptorBindingPartiallyBound, which SAPIEN's renderer requires).
# The backports entry is derived from the machine's own Debian source entry,
# so no package host is named here.
set -euo pipefail

if [ "$(id -u)" != 0 ]; then echo "setup_system.sh: run as root" >&2; exit 2; fi
if ! command -v apt-get >/dev/null; then echo "setup_system.sh: not a Debian machine; install Mesa >= 23 Vulkan drivers yourself" >&2; exit 0; fi

src=/etc/apt/sources.list.d/debian.sources
bp=/etc/apt/sources.list.d/echo-data-backports.sources
if [ ! -f "$bp" ]; then
  if [ -f "$src" ]; then
    # First stanza's URIs line is the main archive mirror of this machine.
    uri=$(awk '/^URIs:/{print $2; exit}' "$src")
    keyring=$(awk '/^Signed-By:/{print $2; exit}' "$src")
  elif [ -f /etc/apt/sources.list ]; then
    uri=$(awk '/^deb /{print $2; exit}' /etc/apt/sources.list)
    keyring=/usr/share/keyrings/debian-archive-keyring.gpg
  fi
  [ -n "${uri:-}" ] || { echo "setup_system.sh: cannot find a Debian source entry to derive backports from" >&2; exit 1; }
  printf 'Types: deb\nURIs: %s\nSuites: bookworm-backports\nComponents: main\nSigned-By: %s\n' \
    "$uri" "${keyring:-/usr/share/keyrings/debian-archive-keyring.gpg}" > "$bp"
fi
export DEBIAN_FRONTEND=noninteractive
apt-get update -qq
apt-get install -y -qq -t bookworm-backports mesa-vulkan-drivers libvulkan1 >/dev/null
apt-get install -y -qq libsndfile1 >/dev/null || true
# FFmpeg 5.1's shared libraries: torchcodec (HF datasets' audio decoder, scripts/setup.sh) loads them.
apt-get install -y -qq --no-install-recommends libavcodec59 libavformat59 libavutil57 libswresample4 libswscale6 libavfilter8 libavdevice59 >/dev/null
echo "setup_system.sh: Mesa $(dpkg-query -W -f='${Version}' mesa-vulkan-drivers) installed"
