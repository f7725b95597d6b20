#!/usr/bin/env bash
# Builds libgphoto2's virtual PTP camera (a virtual USB port driver, `vusb`, that Debian's
# binary packages leave out) from Debian's own source package of libgphoto2, into a cache
# folder outside the repository, for the tests of the gphoto2 camera backend. Idempotent:
# when the cache is complete it only prints its path. Prints the cache folder on success.
#
#   scripts/build-vusb-camera.sh     # cache: ${RIG_VUSB_CACHE:-${XDG_CACHE_HOME:-~/.cache}/rig/libgphoto2-vusb}
#
# Needs: apt-get with access to the Debian archive (a deb-src entry is added when missing),
# a C compiler, make, xz, and libltdl-dev. Only the library, the ptp2 camera driver and the
# vusb port driver are built (about 25 s on two cores).
set -euo pipefail
here="$(cd "$(dirname "$0")/.." && pwd)"
cache="${RIG_VUSB_CACHE:-${XDG_CACHE_HOME:-$HOME/.cache}/rig/libgphoto2-vusb}"
prefix="$cache/prefix"

if [ -f "$cache/complete" ] && [ -f "$cache/iolibs/vusb.so" ]; then
  echo "$cache"
  exit 0
fi

SUDO=""
[ "$(id -u)" -eq 0 ] || SUDO="sudo"
export DEBIAN_FRONTEND=noninteractive
mkdir -p "$cache/src"
cd "$cache/src"

# The source of the very version installed (the tests run our code, built against Debian's
# headers, on this build of the library), else whatever the archive has.
fetch() {
  local installed
  installed="$(dpkg-query -W -f='${Version}' libgphoto2-6 2>/dev/null || true)"
  { [ -n "$installed" ] && apt-get source --download-only "libgphoto2=$installed"; } >"$cache/fetch.log" 2>&1 ||
    apt-get source --download-only libgphoto2 >>"$cache/fetch.log" 2>&1
}
if ! ls libgphoto2_*.orig.tar.* >/dev/null 2>&1; then
  if ! fetch; then
    if grep -qs '^Types:.*deb-src\|^deb-src ' /etc/apt/sources.list /etc/apt/sources.list.d/*; then
      echo "build-vusb-camera: apt-get source libgphoto2 failed:" >&2
      tail -5 "$cache/fetch.log" >&2
      exit 1
    fi
    # Debian's default sources have no deb-src entry: add one for the Debian archive.
    codename="$(. /etc/os-release && echo "${VERSION_CODENAME:-bookworm}")"
    echo "build-vusb-camera: adding a deb-src entry for the Debian archive ($codename)" >&2
    $SUDO tee /etc/apt/sources.list.d/rig-deb-src.sources >/dev/null <<SRC
Types: deb-src
URIs: http://deb.debian.org/debian
Suites: $codename
Components: main
Signed-By: /usr/share/keyrings/debian-archive-keyring.gpg
SRC
    $SUDO apt-get update -qq
    fetch || { echo "build-vusb-camera: apt-get source libgphoto2 failed:" >&2; tail -5 "$cache/fetch.log" >&2; exit 1; }
  fi
fi
orig="$(ls libgphoto2_*.orig.tar.* | head -1)"
version="$(echo "$orig" | sed -E 's/libgphoto2_([0-9.]+)\.orig.*/\1/')"
rm -rf "libgphoto2-$version"
tar xf "$orig"
cd "libgphoto2-$version"
echo "build-vusb-camera: building libgphoto2 $version with the vusb port driver and the ptp2 camlib" >&2
# Nothing optional: the virtual camera needs none of it, and the build does not change with
# what else happens to be installed.
./configure --prefix="$prefix" --enable-vusb --with-camlibs=ptp2 --disable-nls --disable-static \
  --without-jpeg --with-libxml-2.0=no --with-libcurl=no --with-libexif=no \
  --with-libusb-1.0=no --with-libusb=no \
  >"$cache/configure.log" 2>&1 || { tail -20 "$cache/configure.log" >&2; exit 1; }
make -j2 >"$cache/make.log" 2>&1 || { tail -30 "$cache/make.log" >&2; exit 1; }
make install >"$cache/install.log" 2>&1 || { tail -20 "$cache/install.log" >&2; exit 1; }

# libgphoto2 loads one USB port driver and the real one sorts first: a folder with vusb only.
portdir="$(ls -d "$prefix"/lib/libgphoto2_port/*/ | head -1)"
mkdir -p "$cache/iolibs"
cp "$portdir/vusb.so" "$cache/iolibs/"
# The virtual camera serves this folder; capture copies its first JPEG and needs DCIM/.
vcamera="$(ls -d "$prefix"/share/libgphoto2_port/*/ | head -1)vcamera"
mkdir -p "$vcamera/DCIM/100VCAM"
cp "$here/tests/data/vcamera.jpg" "$vcamera/DCIM/100VCAM/VCAM0001.JPG"
cp "$here/tests/data/vcamera.jpg" "$vcamera/vcamera.jpg"
touch "$cache/complete"
echo "$cache"
