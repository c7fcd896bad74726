#!/usr/bin/env bash
# Creates the Debian bookworm arm64 sysroot that toolchains/aarch64-linux-gnu.cmake builds
# against and that qemu runs the arm64 test binaries in. Also installs the cross compiler and
# qemu when they are missing (as root).
#
#   toolchains/make-arm64-sysroot.sh [--rebuild] [--check]
#
#   RANKSLAM_ARM64_SYSROOT  where the sysroot lives (default /var/cache/rankslam/sysroot-arm64)
#   --rebuild               build it again even when the cached one is current
#   --check                 afterwards, cross-build toolchains/check and run it under qemu
#
# Idempotent: a sysroot whose stamp records the same package list, sources and script is reused
# as it is; anything else is rebuilt beside it and swapped in only once complete. Needs root for
# the first build (apt-get, mmdebstrap --mode=root); a current cached sysroot needs nothing.
set -euo pipefail

script_dir=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
sysroot=${RANKSLAM_ARM64_SYSROOT:-/var/cache/rankslam/sysroot-arm64}
suite=bookworm
triplet=aarch64-linux-gnu

# What the product and the unit tests build against. OpenCV: Debian ships OpenCVConfig.cmake
# only in libopencv-dev (which pulls every module, contrib included); the per-module -dev
# packages alone leave find_package(OpenCV) without a config, so the umbrella package it is.
packages=(
  libstdc++-12-dev
  libeigen3-dev libopencv-dev libceres-dev libsuitesparse-dev libopenni2-dev
  libnanoflann-dev libcli11-dev libyaml-cpp-dev libsystemd-dev zlib1g-dev libhwy-dev
  libgtest-dev libgmock-dev libbenchmark-dev
)
tools=(mmdebstrap g++-aarch64-linux-gnu qemu-user-static)

rebuild=0
check=0
for arg in "$@"; do
  case "$arg" in
    --rebuild) rebuild=1 ;;
    --check) check=1 ;;
    -h|--help) sed -n '2,15p' "$0" | sed 's/^# \{0,1\}//'; exit 0 ;;
    *) echo "make-arm64-sysroot.sh: unknown argument '$arg' (try --help)" >&2; exit 2 ;;
  esac
done

log() { printf 'make-arm64-sysroot: %s\n' "$*" >&2; }
die() { log "error: $*"; exit 1; }

apt_updated=0
apt_update_once() {
  if [[ $apt_updated == 0 ]]; then
    apt-get update -qq
    apt_updated=1
  fi
}

install_tools() {
  local missing=()
  command -v mmdebstrap >/dev/null || missing+=(mmdebstrap)
  command -v ${triplet}-g++ >/dev/null || missing+=(g++-aarch64-linux-gnu)
  command -v qemu-aarch64-static >/dev/null || missing+=(qemu-user-static)
  [[ ${#missing[@]} == 0 ]] && return 0
  [[ $EUID == 0 ]] || die "missing ${missing[*]}; run as root or: apt-get install ${tools[*]}"
  log "installing ${missing[*]}"
  apt_update_once
  DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
}

# The Debian repositories apt on this machine already uses, as sources lines for the sysroot:
# the suite, -updates and -security, component main. Falls back to Debian's default mirrors.
debian_sources() {
  local lines
  lines=$(apt-get indextargets --format '$(REPO_URI) $(RELEASE) $(COMPONENT) $(IDENTIFIER)' 2>/dev/null |
          awk -v s="$suite" '$4 == "Packages" && $3 == "main" &&
                             ($2 == s || $2 == s "-updates" || $2 == s "-security") {
                               uri = $1; sub(/\/$/, "", uri); print "deb " uri " " $2 " main" }' |
          sort -u)
  if [[ -z $lines ]] || ! grep -q " $suite main\$" <<<"$lines"; then
    lines=$(printf '%s\n' "deb http://deb.debian.org/debian $suite main" \
                          "deb http://deb.debian.org/debian $suite-updates main" \
                          "deb http://deb.debian.org/debian-security $suite-security main")
  fi
  printf '%s\n' "$lines"
}

# Makes every absolute symlink inside the sysroot relative, so it resolves inside the sysroot
# for the linker and for qemu instead of pointing at the build machine's own files.
relativise_symlinks() {
  local root=$1 link target
  while IFS= read -r -d '' link; do
    target=$(readlink "$link")
    ln -sfn "$(realpath -m -s --relative-to="$(dirname "$link")" "$root$target")" "$link"
  done < <(find "$root" -xdev -path "$root/dev" -prune -o -type l -lname '/*' -print0)
}

# Reads one downloaded package into $2: its control files (for the alternatives and the dpkg
# database) and, for library packages, its file list (dpkg-shlibdeps maps a library to its
# package through it).
index_deb() {
  local deb=$1 out=$2 pkg arch multi name
  pkg=$(dpkg-deb -f "$deb" Package)
  arch=$(dpkg-deb -f "$deb" Architecture)
  multi=$(dpkg-deb -f "$deb" Multi-Arch)
  name=$pkg
  [[ $multi == same ]] && name=$pkg:$arch
  dpkg-deb -e "$deb" "$out/control/$name"
  # Only shared-library packages (those with shlibs or symbols) are looked up by file.
  [[ -f $out/control/$name/shlibs || -f $out/control/$name/symbols ]] || return 0
  dpkg-deb -c "$deb" | awk '{ p = $6; sub(/^\./, "", p); sub(/\/$/, "", p); if (p == "") p = "/."; print p }' \
    > "$out/control/$name/list"
}
export -f index_deb

# --variant=extract runs no maintainer scripts, so the update-alternatives links (BLAS, LAPACK
# and their headers and .pc files) are missing. Recreate each group's highest-priority choice,
# as update-alternatives would in automatic mode, from the packages' own postinst scripts.
make_alternatives_links() {
  local root=$1 index=$2 name prio link path
  cat "$index"/control/*/postinst 2>/dev/null |
    sed -e ':a' -e '/\\$/N; s/\\\n/ /; ta' |
    awk '{ for (i = 1; i <= NF; ++i) if ($i == "--install" && $(i - 1) ~ /update-alternatives$/) {
             name = $(i + 2); prio = $(i + 4)
             print name, prio, $(i + 1), $(i + 3)
             for (j = i + 5; j + 3 <= NF; ++j) if ($j == "--slave") print name, prio, $(j + 1), $(j + 3)
           } }' |
    tr -d '"' | sort -k1,1 -k2,2nr | awk '!seen[$1]++ { best[$1] = $2 } best[$1] == $2' |
    while read -r name prio link path; do
      [[ $link == /usr/* && $path == /usr/* && -e $root$path ]] || continue
      ln -sfn "$(realpath -m -s --relative-to="$(dirname "$root$link")" "$root$path")" "$root$link"
    done
}

# Debian's CeresTargets.cmake names BLAS/LAPACK/ATLAS by absolute build-machine paths
# (/usr/lib/<triplet>/liblapack.so ...), which a cross build would take from the host. Plain
# library names let the linker find them in the sysroot.
patch_cmake_configs() {
  local root=$1 file
  while IFS= read -r -d '' file; do
    sed -E -i "s#/usr/lib/${triplet}/lib([A-Za-z0-9_+-]+)\\.so([;\"])#\\1\\2#g" "$file"
  done < <(grep -rlZE "/usr/lib/${triplet}/lib[A-Za-z0-9_+-]+\\.so[;\"]" --include='*.cmake' \
             "$root/usr/lib/$triplet/cmake" "$root/usr/share" 2>/dev/null || true)
}

# OpenNI2 changes into its drivers directory before loading them, and qemu redirects file opens
# into the sysroot but not chdir; naming the directory by its host path lets the drivers load
# under the emulator. The robot's own OpenNI.ini is untouched (this file is the sysroot's).
point_openni2_at_drivers() {
  local root=$1 final=$2 ini=$1/etc/openni2/OpenNI.ini
  [[ -f $ini ]] || return 0
  sed -i "s#^;\\{0,1\\}Repository=.*#Repository=$final/usr/lib/$triplet/OpenNI2/Drivers#" "$ini"
}

# A dpkg database for the extracted packages, so the dependencies of packages built for the
# robot are computed from it (deploy/shlibdeps.sh) and checked against it
# (deploy/check-package.sh).
write_dpkg_database() {
  local root=$1 index=$2 dir name file
  for dir in "$index"/control/*/; do
    awk 'NR == 1 { print; print "Status: install ok installed"; next } { print }' "$dir/control"
    echo
  done > "$root/var/lib/dpkg/status"
  echo 1 > "$root/var/lib/dpkg/info/format"  # multiarch layout: info/<pkg>:<arch>.list
  for dir in "$index"/control/*/; do
    name=$(basename "$dir")
    [[ -f $dir/list ]] && cp "$dir/list" "$root/var/lib/dpkg/info/$name.list"
    for file in shlibs symbols triggers conffiles md5sums; do
      [[ -f $dir/$file ]] && cp "$dir/$file" "$root/var/lib/dpkg/info/$name.$file"
    done
  done
}

build_sysroot() {
  local dir=$1 final=$2 sources_text=$3
  local -a sources
  mapfile -t sources <<<"$sources_text"
  rm -rf "$dir"
  mkdir -p "$(dirname "$dir")"
  log "creating $dir (mmdebstrap, arm64, $suite)"
  mmdebstrap --quiet --mode=root --variant=extract --architectures=arm64 \
    --skip=cleanup/apt/cache \
    --include="$(IFS=,; echo "${packages[*]}")" \
    "$suite" "$dir" "${sources[@]}"
  log "extracted in $((SECONDS - start)) s; fixing the extracted tree (symlinks, alternatives, CMake configs, dpkg database)"
  local index=$dir/var/cache/apt/archives/index
  mkdir -p "$dir/var/lib/dpkg/info" "$index/control"
  find "$dir/var/cache/apt/archives" -maxdepth 1 -name '*.deb' -print0 |
    xargs -0 -P "$(nproc)" -I{} bash -c 'set -euo pipefail; index_deb "$1" "$2"' _ {} "$index"
  relativise_symlinks "$dir"
  make_alternatives_links "$dir" "$index"
  patch_cmake_configs "$dir"
  point_openni2_at_drivers "$dir" "$final"
  write_dpkg_database "$dir" "$index"
  rm -rf "$index" "$dir"/var/cache/apt/archives/*.deb
  log "fixed in $((SECONDS - start)) s"
  [[ -f $dir/usr/lib/$triplet/cmake/opencv4/OpenCVConfig.cmake && -e $dir/usr/lib/$triplet/libblas.so.3 ]] ||
    die "sysroot in $dir is incomplete after extraction"
}

run_check() {
  local build_dir
  build_dir=$(mktemp -d)
  trap 'rm -rf "$build_dir"' RETURN
  log "checking: cross-building toolchains/check and running it under qemu"
  cmake -S "$script_dir/check" -B "$build_dir" -G Ninja -DCMAKE_BUILD_TYPE=Release \
        -DCMAKE_TOOLCHAIN_FILE="$script_dir/aarch64-linux-gnu.cmake" \
        -DRANKSLAM_ARM64_SYSROOT="$sysroot" > "$build_dir/configure.log" ||
    { cat "$build_dir/configure.log"; die "configuring toolchains/check failed"; }
  cmake --build "$build_dir" -j2
  ctest --test-dir "$build_dir" --output-on-failure
}

install_tools

sources_text=$(debian_sources)
stamp_text=$(printf 'path: %s\nsuite: %s\narchitecture: arm64\npackages: %s\nsources:\n%s\nscript-sha256: %s\n' \
  "$sysroot" "$suite" "$(printf '%s\n' "${packages[@]}" | sort | tr '\n' ' ' | sed 's/ $//')" \
  "$sources_text" "$(sha256sum "$0" | cut -d' ' -f1)")
stamp=$sysroot/.rankslam-sysroot-stamp

# One run at a time per sysroot: a second run waits, then finds the first one's result current.
mkdir -p "$(dirname "$sysroot")" 2>/dev/null || true
if { exec 9>>"$sysroot.lock"; } 2>/dev/null; then
  flock 9
fi

if [[ $rebuild == 0 && -f $stamp ]] && [[ "$(cat "$stamp")" == "$stamp_text" ]]; then
  log "cached sysroot is current: $sysroot"
else
  [[ $EUID == 0 ]] || die "$sysroot is missing or out of date; building it needs root"
  [[ -f $stamp ]] && log "sysroot at $sysroot is out of date or --rebuild given; rebuilding"
  start=$SECONDS
  build_sysroot "$sysroot.new" "$sysroot" "$sources_text"
  printf '%s\n' "$stamp_text" > "$sysroot.new/.rankslam-sysroot-stamp"
  rm -rf "$sysroot"
  mv "$sysroot.new" "$sysroot"
  log "sysroot ready in $((SECONDS - start)) s: $sysroot"
fi

if [[ $check == 1 ]]; then
  run_check
fi
echo "$sysroot"
