#!/usr/bin/env bash
# Runs a command against libgphoto2's virtual camera built by build-vusb-camera.sh: the
# environment that points libgphoto2 at it (IOLIBS with only vusb.so, CAMLIBS,
# LD_LIBRARY_PATH, a writable XDG_CONFIG_HOME), in a folder holding the '>NAME' device file
# (USB vendor and product of the virtual body, b0 04 37 04) and NAME -> /dev/null.
# The command reaches the body as model "Nikon DSC D750" on port "usb:>vcam".
set -euo pipefail
cache="$("$(dirname "$0")/build-vusb-camera.sh")"
prefix="$cache/prefix"
work="$(mktemp -d "${TMPDIR:-/tmp}/rig-vusb.XXXXXX")"
trap 'rm -rf "$work"' EXIT
printf '\xb0\x04\x37\x04' >"$work/>vcam"
ln -s /dev/null "$work/vcam"
mkdir -p "$work/config"
export IOLIBS="$cache/iolibs"
export CAMLIBS="$(ls -d "$prefix"/lib/libgphoto2/*/ | head -1)"
export LD_LIBRARY_PATH="$prefix/lib${LD_LIBRARY_PATH:+:$LD_LIBRARY_PATH}"
export XDG_CONFIG_HOME="$work/config"
export RIG_VUSB_PORT="usb:>vcam" RIG_VUSB_MODEL="Nikon DSC D750"
export RIG_VUSB_JPEG="$(ls -d "$prefix"/share/libgphoto2_port/*/ | head -1)vcamera/DCIM/100VCAM/VCAM0001.JPG"
cd "$work"
"$@"
