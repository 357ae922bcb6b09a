#!/usr/bin/env bash
# Intel Open Image Denoise 2.5.1 for `--denoiser oidn`: unpacks the official Linux libraries,
# which the PyPI wheel pyoidn==2.5.1.0 ships, to target/oidn/ (once), and prints the folder to
# build against:
#
#   OIDN_DIR=$(tools/setup-oidn.sh) cargo build --release -p phr --features oidn
#
# The binary finds the libraries there by its run path (no LD_LIBRARY_PATH needed). Only the
# CPU device is kept; the GPU device modules (CUDA, HIP, SYCL: most of the 88 MB) are dropped.
set -euo pipefail
cd "$(dirname "$0")/.."
dest="$PWD/target/oidn"
if [ ! -e "$dest/lib/libOpenImageDenoise.so.2" ]; then
    tmp=$(mktemp -d "$PWD/target/oidn-setup.XXXXXX")
    trap 'rm -rf "$tmp"' EXIT
    python3 -m pip download --quiet --no-deps --only-binary=:all: pyoidn==2.5.1.0 -d "$tmp" >&2
    python3 -m zipfile -e "$tmp"/pyoidn-2.5.1.0-*.whl "$tmp/wheel"
    # Staged, then moved in whole: an interrupted run leaves no half install behind.
    mkdir -p "$tmp/oidn/lib"
    for lib in libOpenImageDenoise.so libOpenImageDenoise.so.2 libOpenImageDenoise.so.2.5.1 \
        libOpenImageDenoise_core.so.2.5.1 libOpenImageDenoise_device_cpu.so.2.5.1 libtbb.so.12; do
        cp "$tmp/wheel/pyoidn/oidn/lib/$lib" "$tmp/oidn/lib/"
    done
    rm -rf "$dest"
    mv "$tmp/oidn" "$dest"
fi
echo "$dest"
