#!/usr/bin/env bash
# Installs every build and test dependency of rig from Debian 12 packages. Idempotent:
# a second run installs nothing and takes a second.
set -euo pipefail

packages=(
  build-essential cmake ninja-build pkg-config git
  # hardware (each optional at build time; installed here so every backend is built)
  libgphoto2-dev libgpiod-dev libserialport-dev
  # processing
  libopencv-core-dev libopencv-imgproc-dev libopencv-imgcodecs-dev libopencv-photo-dev
  libopencv-videoio-dev libopenexr-dev libeigen3-dev libopenblas-dev libjpeg-dev
  libraw-dev libtiff-dev libexif-dev
  # infrastructure
  libspdlog-dev libfmt-dev libtomlplusplus-dev libcli11-dev nlohmann-json3-dev
  zlib1g-dev
  # collections (rig collection: share/rig/Snakefile); a one-node Slurm cluster on localhost
  # for the test that runs a collection as Slurm jobs (scripts/slurm-local.sh), with its
  # accounting (sacct: slurmdbd on a MariaDB server of the cluster's own)
  snakemake slurm-wlm munge slurmdbd mariadb-server
  # rig daemon: its HTTP+JSON API; chromium: the status page tested in a headless browser
  libcpp-httplib-dev chromium
  # tests and benchmarks (libltdl-dev, xz-utils: building libgphoto2's virtual camera)
  libgtest-dev libgmock-dev libbenchmark-dev libltdl-dev xz-utils
  # the relighting page's browser test (rig view): a headless browser, a loopback HTTP server
  chromium libcpp-httplib-dev
  # the sanitizer build and the fuzzers (scripts/test-sanitize.sh, scripts/fuzz.sh): clang,
  # its sanitizer and libFuzzer runtimes, llvm-symbolizer for the reports' stack traces
  clang-14 libclang-rt-14-dev llvm-14
)

missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -eq 0 ]; then
  exit 0
fi
echo "setup: installing ${missing[*]}"
SUDO=""
[ "$(id -u)" -eq 0 ] || SUDO="sudo"
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update -qq
$SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}"
