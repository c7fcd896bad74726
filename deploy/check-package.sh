#!/usr/bin/env bash
# Checks that a rankslam .deb installs on Debian bookworm with nothing missing: apt resolves it
# (simulation only, nothing is installed) against a system that already has the package's
# library dependencies, fetching anything else from the Debian archive. For a foreign
# architecture (arm64 on an amd64 machine) that system is the arm64 sysroot
# (toolchains/make-arm64-sysroot.sh), with its own package lists fetched into a temporary
# directory; for this machine's architecture it is this machine.
#
#   deploy/check-package.sh PACKAGE.deb [SYSROOT]
#
# SYSROOT defaults to RANKSLAM_ARM64_SYSROOT, else /var/cache/rankslam/sysroot-arm64.
# Prints the package's control data and contents, then apt's plan; exits non-zero when apt
# finds unmet dependencies.
set -euo pipefail

deb=${1:?usage: check-package.sh PACKAGE.deb [SYSROOT]}
[[ -f $deb ]] || { echo "check-package.sh: no such package: $deb" >&2; exit 1; }
deb=$(realpath "$deb")
sysroot=${2:-${RANKSLAM_ARM64_SYSROOT:-/var/cache/rankslam/sysroot-arm64}}

dpkg-deb --info "$deb"
dpkg-deb --contents "$deb"

arch=$(dpkg-deb -f "$deb" Architecture)
echo
if [[ $arch == "$(dpkg --print-architecture)" || $arch == all ]]; then
  echo "apt simulation on this machine ($arch):"
  apt-get -s install "$deb"
  exit
fi

[[ -f $sysroot/var/lib/dpkg/status ]] ||
  { echo "check-package.sh: no $arch sysroot with a dpkg database at $sysroot" >&2; exit 1; }
[[ $(cat "$sysroot/var/lib/dpkg/arch" 2>/dev/null | head -1) == "$arch" ]] ||
  { echo "check-package.sh: $sysroot is not a $arch sysroot" >&2; exit 1; }

state=$(mktemp -d)
trap 'rm -rf "$state"' EXIT
mkdir -p "$state/lists/partial" "$state/cache/archives/partial"
# The sysroot's own sources and installed packages; lists and cache kept out of the sysroot;
# the archive keys are this machine's.
apt_options=(
  -o Dir="$sysroot"
  -o Dir::State::lists="$state/lists"
  -o Dir::Cache="$state/cache"
  -o Dir::Etc::trusted=/etc/apt/trusted.gpg
  -o Dir::Etc::trustedparts=/etc/apt/trusted.gpg.d
  -o APT::Architecture="$arch"
  -o APT::Sandbox::User=root
  -o Debug::NoLocking=1
)
apt-get "${apt_options[@]}" -qq update
echo "apt simulation on the $arch sysroot $sysroot:"
apt-get "${apt_options[@]}" -s install "$deb"
