#!/usr/bin/env bash
# Build GROMACS for this machine's SIMD from Debian's own source package: the "native" anchor
# that scripts/head_to_head.py and scripts/production_peers.py run as `gromacs-native` beside
# Debian's `gmx` package.
#
# Debian's gromacs 2022.5 binary package is configured with -DGMX_SIMD=SSE4.1 for portability
# (its debian/rules); a user who compiles GROMACS gets GROMACS's own choice for the CPU
# (-DGMX_SIMD=AUTO: AVX_512 on an AVX-512 Intel Xeon, AVX2_256 without AVX-512). This script
# builds the same 2022.5 sources that way, once, into a cache folder outside the repository:
#
#   1. a deb-src line for Debian bookworm main is added when `apt-get source` has none;
#   2. `apt-get source --download-only gromacs`, the orig tarball unpacked;
#   3. Debian's /usr/bin/cmake (apt-get install cmake libfftw3-dev when missing; a pip cmake
#      4.x fails on this tree) with -DGMX_SIMD=AUTO, FFTW from Debian, no MPI, no GPU, OpenMP,
#      mixed precision (GROMACS's default);
#   4. `make gmx && make install` into the prefix.
#
# About 12 minutes on 2 idle cores; 85 minutes at nice 10-15 on 2 cores loaded by other work
# (load 16-22). A later call finds the installed bin/gmx and does nothing.
#
#   scripts/build_gromacs_native.sh            # build when missing; prints the gmx path last
#   scripts/build_gromacs_native.sh --path     # print where gmx is (or would be), build nothing
#   nice -n 15 scripts/build_gromacs_native.sh # on a shared machine
#
# Environment: LONGSTEP_GROMACS_NATIVE (the install prefix; default
# ${XDG_CACHE_HOME:-~/.cache}/longstep/gromacs-native), GMX_BUILD_JOBS (make -j; default nproc).
# Needs root or sudo for apt-get. The build tree is kept beside the prefix (PREFIX-src) so an
# interrupted build resumes where it stopped.
set -euo pipefail

cache="${XDG_CACHE_HOME:-$HOME/.cache}/longstep"
prefix="${LONGSTEP_GROMACS_NATIVE:-$cache/gromacs-native}"
gmx="$prefix/bin/gmx"

if [[ "${1:-}" == "--path" ]]; then
    echo "$gmx"
    exit 0
elif [[ $# -gt 0 ]]; then
    echo "usage: $0 [--path]" >&2
    exit 2
fi

if [[ -x "$gmx" ]] && "$gmx" --version >/dev/null 2>&1; then
    echo "gromacs-native: already built at $prefix" >&2
    echo "$gmx"
    exit 0
fi

as_root() {
    if [[ $(id -u) -eq 0 ]]; then
        "$@"
    elif command -v sudo >/dev/null; then
        sudo "$@"
    else
        echo "gromacs-native: '$*' needs root (no sudo found)" >&2
        exit 1
    fi
}

# 1. deb-src for bookworm main, only when apt knows no source package for gromacs.
if ! apt-cache showsrc gromacs 2>/dev/null | grep -q '^Package: gromacs'; then
    echo "gromacs-native: adding a deb-src line for Debian bookworm main" >&2
    # The same Signed-By as Debian's own deb lines (apt refuses two values for one source).
    keyring=/usr/share/keyrings/debian-archive-keyring.gpg
    opts=""
    [[ -f $keyring ]] && opts="[signed-by=$keyring] "
    echo "deb-src ${opts}http://deb.debian.org/debian bookworm main" |
        as_root tee /etc/apt/sources.list.d/longstep-bookworm-src.list >/dev/null
    as_root apt-get update -qq
fi

# 3 (tools first). Debian's cmake and FFTW headers.
need=()
[[ -x /usr/bin/cmake ]] || need+=(cmake)
[[ -f /usr/include/fftw3.h ]] || need+=(libfftw3-dev)
command -v g++ >/dev/null || need+=(g++)
command -v make >/dev/null || need+=(make)
if [[ ${#need[@]} -gt 0 ]]; then
    echo "gromacs-native: apt-get install ${need[*]}" >&2
    as_root env DEBIAN_FRONTEND=noninteractive apt-get install -y -qq "${need[@]}" >&2
fi

# 2. The sources.
src_root="$prefix-src"
mkdir -p "$src_root"
cd "$src_root"
if ! ls gromacs_*.orig.tar.gz >/dev/null 2>&1; then
    echo "gromacs-native: apt-get source --download-only gromacs" >&2
    apt-get source --download-only gromacs >&2
fi
orig=$(ls gromacs_*.orig.tar.gz | sort | tail -n 1)
# gromacs_2022.5.orig.tar.gz unpacks to gromacs-2022.5/
version=${orig#gromacs_}
tree="gromacs-${version%.orig.tar.gz}"
if [[ ! -f "$tree/CMakeLists.txt" ]]; then
    echo "gromacs-native: unpacking $orig" >&2
    tar -xzf "$orig"
fi

# 3. Configure.
mkdir -p build
cd build
if [[ ! -f CMakeCache.txt ]]; then
    echo "gromacs-native: configuring $tree (GMX_SIMD=AUTO)" >&2
    /usr/bin/cmake "../$tree" \
        -DCMAKE_INSTALL_PREFIX="$prefix" \
        -DCMAKE_BUILD_TYPE=Release \
        -DGMX_SIMD=AUTO -DGMX_GPU=OFF -DGMX_MPI=OFF -DGMX_OPENMP=ON \
        -DGMX_FFT_LIBRARY=fftw3 -DGMX_BUILD_OWN_FFTW=OFF \
        -DBUILD_TESTING=OFF -DCMAKE_DISABLE_FIND_PACKAGE_MPI=ON >&2
fi

# 4. Build and install.
jobs="${GMX_BUILD_JOBS:-$(nproc)}"
echo "gromacs-native: make -j$jobs gmx (about 12 min on 2 idle cores, far longer if loaded)" >&2
make -j"$jobs" gmx >&2
make -j"$jobs" install >&2
"$gmx" --version 2>/dev/null | grep -E 'GROMACS version|SIMD instructions' >&2
echo "$gmx"
