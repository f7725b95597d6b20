#!/usr/bin/env bash
# Builds libgphoto2's virtual PTP camera (a virtual USB port driver, `vusb`, that Debian's
# binary packages leave out) from Debian's own source package of libgphoto2, into a cache
# folder outside the repository, for the tests of the gphoto2 camera backend. Idempotent:
# when the cache is complete it only prints its path. Prints the cache folder on success.
#
#   scripts/build-vusb-camera.sh            # cache: ${XDG_CACHE_HOME:-~/.cache}/rig/libgphoto2-vusb
set -euo pipefail
here="$(cd "$(dirname "$0")/.." && pwd)"
cache="${RIG_VUSB_CACHE:-${XDG_CACHE_HOME:-$HOME/.cache}/rig/libgphoto2-vusb}"
prefix="$cache/prefix"
portdir="$prefix/lib/libgphoto2_port/0.12.1"
vcamera="$prefix/share/libgphoto2_port/0.12.1/vcamera"

if [ -f "$cache/complete" ] && [ -f "$cache/iolibs/vusb.so" ]; then
  echo "$cache"
  exit 0
fi

SUDO=""
[ "$(id -u)" -eq 0 ] || SUDO="sudo"
export DEBIAN_FRONTEND=noninteractive
mkdir -p "$cache/src"
cd "$cache/src"
if ! ls libgphoto2_*.orig.tar.* >/dev/null 2>&1; then
  if ! apt-get source --download-only libgphoto2 >/dev/null 2>&1; then
    # Debian 12's default sources have no deb-src entry: add one for the Debian archive.
    echo "build-vusb-camera: adding a deb-src entry for the Debian archive" >&2
    $SUDO tee /etc/apt/sources.list.d/rig-deb-src.sources >/dev/null <<'SRC'
Types: deb-src
URIs: http://deb.debian.org/debian
Suites: bookworm
Components: main
Signed-By: /usr/share/keyrings/debian-archive-keyring.gpg
SRC
    $SUDO apt-get update -qq
    apt-get source --download-only libgphoto2 >/dev/null 2>&1
  fi
fi
orig="$(ls libgphoto2_*.orig.tar.* | head -1)"
version="$(echo "$orig" | sed -E 's/libgphoto2_([0-9.]+)\.orig.*/\1/')"
rm -rf "libgphoto2-$version"
tar xf "$orig"
cd "libgphoto2-$version"
echo "build-vusb-camera: building libgphoto2 $version with the vusb port driver and the ptp2 camlib" >&2
./configure --prefix="$prefix" --enable-vusb --with-camlibs=ptp2 --disable-nls --without-jpeg \
  >"$cache/configure.log" 2>&1 || { tail -20 "$cache/configure.log" >&2; exit 1; }
make -j2 >"$cache/make.log" 2>&1 || { tail -30 "$cache/make.log" >&2; exit 1; }
make install >"$cache/install.log" 2>&1 || { tail -20 "$cache/install.log" >&2; exit 1; }

# libgphoto2 loads one USB port driver and the real one sorts first: a folder with vusb only.
mkdir -p "$cache/iolibs"
cp "$portdir/vusb.so" "$cache/iolibs/"
# The virtual camera serves this folder; capture copies its first JPEG and needs DCIM/.
mkdir -p "$vcamera/DCIM/100VCAM"
cp "$here/tests/data/vcamera.jpg" "$vcamera/DCIM/100VCAM/VCAM0001.JPG"
cp "$here/tests/data/vcamera.jpg" "$vcamera/vcamera.jpg"
touch "$cache/complete"
echo "$cache"
