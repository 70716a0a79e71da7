#!/usr/bin/env bash
# Installs Debian's Point Cloud Library (libpcl-dev) and builds the PCL SHOT reference tool
# (tools/pcl-shot/pcl_shot.cpp) into "${CARGO_TARGET_DIR:-<repo>/target}/pcl-shot/pcl_shot".
#
# The motif-core integration test `tests/shot.rs` compares our SHOT with this tool's output when
# the binary exists (override its path with MOTIF_PCL_SHOT) and skips the comparison otherwise.
#
# Idempotent: the apt step runs only when libpcl-dev is missing, the compile step only when the
# binary is older than its source. Needs root (or sudo) for apt-get.
set -euo pipefail

repo="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
src="$repo/tools/pcl-shot/pcl_shot.cpp"
out_dir="${CARGO_TARGET_DIR:-$repo/target}/pcl-shot"
bin="$out_dir/pcl_shot"

sudo_cmd=()
if [ "$(id -u)" -ne 0 ]; then
    sudo_cmd=(sudo)
fi

installed() {
    dpkg-query -W -f='${Status}' "$1" 2>/dev/null | grep -q "install ok installed"
}

need=()
for pkg in libpcl-dev g++ pkg-config; do
    installed "$pkg" || need+=("$pkg")
done

if [ "${#need[@]}" -gt 0 ]; then
    echo "pcl-shot-setup: installing ${need[*]} with apt-get (no recommends)"
    start=$(date +%s)
    before=$(df --output=used -B1M / | tail -n 1)
    "${sudo_cmd[@]}" apt-get update
    "${sudo_cmd[@]}" env DEBIAN_FRONTEND=noninteractive apt-get install -y --no-install-recommends "${need[@]}"
    after=$(df --output=used -B1M / | tail -n 1)
    echo "pcl-shot-setup: apt-get took $(($(date +%s) - start)) s and $((after - before)) MiB of disk"
else
    echo "pcl-shot-setup: libpcl-dev, g++ and pkg-config already installed"
fi

# PCL's pkg-config files name the include directory; fall back to the usual Debian layout.
pcl_pc="$(pkg-config --list-all 2>/dev/null | awk '/^pcl_features-/ {print $1; exit}')"
if [ -n "$pcl_pc" ]; then
    pcl_inc="$(pkg-config --variable=includedir "$pcl_pc")/pcl-$(pkg-config --modversion "$pcl_pc" | cut -d. -f1,2)"
else
    pcl_inc="$(ls -d /usr/include/pcl-1.* | sort -V | tail -n 1)"
fi
[ -d "$pcl_inc" ] || { echo "pcl-shot-setup: PCL headers not found (looked for $pcl_inc)" >&2; exit 1; }

mkdir -p "$out_dir"
if [ -x "$bin" ] && [ "$bin" -nt "$src" ] && [ "$bin" -nt "${BASH_SOURCE[0]}" ]; then
    echo "pcl-shot-setup: $bin is up to date"
    exit 0
fi

echo "pcl-shot-setup: compiling $src against $pcl_inc"
# -O2 -DNDEBUG as in a CMake Release build; only the PCL libraries SHOTEstimation needs.
g++ -std=c++17 -O2 -DNDEBUG -march=x86-64 \
    -I"$pcl_inc" -I/usr/include/eigen3 \
    "$src" -o "$bin" \
    -lpcl_features -lpcl_search -lpcl_kdtree -lpcl_common
echo "pcl-shot-setup: built $bin"
