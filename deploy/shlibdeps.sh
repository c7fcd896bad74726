#!/usr/bin/env bash
# Prints the Debian "Depends" of ELF binaries, computed by dpkg-shlibdeps from the libraries
# they link. With --sysroot (cross builds) the libraries, their packages and the packages'
# shlibs/symbols files are taken from that sysroot's dpkg database
# (toolchains/make-arm64-sysroot.sh writes one); otherwise from this machine's.
#
#   deploy/shlibdeps.sh [--sysroot DIR --arch DEBIAN_ARCH --multiarch TRIPLET] BINARY...
set -euo pipefail

sysroot=
arch=
multiarch=
while [[ $# -gt 0 ]]; do
  case "$1" in
    --sysroot) sysroot=$2; shift 2 ;;
    --arch) arch=$2; shift 2 ;;
    --multiarch) multiarch=$2; shift 2 ;;
    --) shift; break ;;
    -*) echo "shlibdeps.sh: unknown option $1" >&2; exit 2 ;;
    *) break ;;
  esac
done
[[ $# -gt 0 ]] || { echo "shlibdeps.sh: no binary given" >&2; exit 2; }
command -v dpkg-shlibdeps >/dev/null ||
  { echo "shlibdeps.sh: dpkg-shlibdeps not found (apt-get install dpkg-dev)" >&2; exit 1; }

binaries=()
for binary in "$@"; do
  [[ -f $binary ]] || { echo "shlibdeps.sh: no such binary: $binary" >&2; exit 1; }
  binaries+=("$(realpath "$binary")")
done

work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
mkdir -p "$work/debian"
# dpkg-shlibdeps wants a source package's control file in the working directory.
printf 'Source: rankslam\n\nPackage: rankslam\nArchitecture: any\n' > "$work/debian/control"

args=(-O)
if [[ -n $sysroot ]]; then
  [[ -n $arch && -n $multiarch ]] || { echo "shlibdeps.sh: --sysroot needs --arch and --multiarch" >&2; exit 2; }
  sysroot=$(realpath "$sysroot")
  [[ -f $sysroot/var/lib/dpkg/status ]] ||
    { echo "shlibdeps.sh: $sysroot has no dpkg database (var/lib/dpkg/status)" >&2; exit 1; }
  args+=(--admindir="$sysroot/var/lib/dpkg"
         -l"$sysroot/usr/lib/$multiarch" -l"$sysroot/lib/$multiarch")
  export DEB_HOST_ARCH=$arch DEB_HOST_MULTIARCH=$multiarch
  # dpkg-shlibdeps asks dpkg-query which package owns each library by the path it found, which
  # here starts with the sysroot. This dpkg-query answers for the path inside the sysroot and
  # hands the sysroot-prefixed path back.
  mkdir -p "$work/bin"
  cat > "$work/bin/dpkg-query" <<EOF
#!/usr/bin/env bash
root='$sysroot'
if [[ \${1:-} != --search ]]; then exec /usr/bin/dpkg-query "\$@"; fi
shift; [[ \${1:-} == -- ]] && shift
paths=()
for p in "\$@"; do paths+=("\${p#"\$root"}"); done
/usr/bin/dpkg-query --admindir="\$root/var/lib/dpkg" --search -- "\${paths[@]}" |
  sed -E "s#^([^:]+(:[a-z0-9]+)?(, [^:]+(:[a-z0-9]+)?)*): /#\\1: \$root/#"
EOF
  chmod +x "$work/bin/dpkg-query"
  export PATH=$work/bin:$PATH
fi

cd "$work"
# The binaries are analysed where they were built, not in a package tree; dpkg-shlibdeps warns
# about that, and about libraries pulled in by third-party link interfaces. Only errors matter.
output=$(dpkg-shlibdeps "${args[@]}" "${binaries[@]}" 2> "$work/stderr") || {
  cat "$work/stderr" >&2
  exit 1
}
grep -v -e 'should already be installed in' -e 'could avoid a useless dependency' "$work/stderr" >&2 || true
depends=${output#shlibs:Depends=}
[[ $output == shlibs:Depends=* && -n $depends ]] ||
  { echo "shlibdeps.sh: dpkg-shlibdeps printed no dependencies: $output" >&2; exit 1; }
printf '%s\n' "$depends"
