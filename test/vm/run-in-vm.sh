#!/usr/bin/env bash
# Runs a command against a real Linux kernel: boots Debian's own kernel in qemu (KVM where it
# works, else TCG), loads the
# SocketCAN (vcan), V4L2 (vivid) and 9p modules, creates vcan0, shares the host's root file
# system read-only over 9p and runs the command chrooted into it, so the host's binaries and
# libraries run on the VM's kernel. Prints the command's output as it runs and exits with its
# exit code.
#
#   test/vm/run-in-vm.sh [--] COMMAND [ARGS...]
#
# Exit codes: the command's own; 77 when qemu, busybox or the kernel cannot be obtained at all
# (ctest SKIP_RETURN_CODE); 125 when the VM hung, crashed or printed no result line.
#
# Environment:
#   RANKSLAM_VM_CACHE       kernel cache (default /var/cache/rankslam/vm when writable,
#                           else ${XDG_CACHE_HOME:-~/.cache}/rankslam/vm)
#   RANKSLAM_VM_KERNEL_PKG  kernel package (default: the one linux-image-amd64 depends on)
#   RANKSLAM_VM_TIMEOUT_S   wall-clock limit for the whole VM run (default 240)
#   RANKSLAM_VM_MEMORY_MB   guest memory (default 1024)
#   RANKSLAM_VM_CPUS        guest CPUs (default 1: one emulated CPU keeps up with the camera
#                           better than two competing for the host's cores)
#   RANKSLAM_VM_CPU         emulated CPU model under TCG (default max: the newest instruction sets
#                           TCG has); KVM runs the host's
#   RANKSLAM_VM_ACCEL       kvm, tcg or auto (default): KVM when /dev/kvm is usable and a probe
#                           boot under it finishes (remembered per host kernel and qemu version)
#   RANKSLAM_VM_KEEP        when set, keep the run directory (console log, command output files)
#   RANKSLAM_VM_NO_INSTALL  when set, never run apt-get (missing tools mean skip)
#   RANKSLAM_VM_FILES_TO    when set, the files the command wrote are copied to this directory
#   RANKSLAM_VM_VIVID_OPTS  module options for vivid (default n_devs=1)
# Variables named GTEST_* are passed into the VM; the command also sees RANKSLAM_VM=1,
# RANKSLAM_VM_OUT (a directory whose files reach the host; kept when the command fails or
# RANKSLAM_VM_KEEP is set) and TMPDIR (a tmpfs). The guest's root is the host's, read-only,
# with fresh /proc, /sys, /dev, /run and, unless the command lives there, /tmp.
set -euo pipefail

readonly kSkip=77
readonly kVmFailure=125
readonly kResultTag="RANKSLAM-VM-RESULT"
# Modules the guest loads, with their dependencies resolved from modules.dep at cache time.
readonly kRootModules=(
  virtio_pci 9pnet_virtio 9p   # host root and output share
  can-raw vcan sch_netem       # SocketCAN on vcan0; netem holds frames to fill a TX queue
  vivid                        # V4L2 test-pattern capture devices
)
readonly kPackages=(qemu-system-x86 busybox-static can-utils)

log() { printf 'run-in-vm: %s\n' "$*" >&2; }
skip() { log "SKIP: $*"; exit "$kSkip"; }
fail() { log "FAIL: $*"; exit "$kVmFailure"; }

if [[ "${1:-}" == "--" ]]; then shift; fi
if [[ $# -eq 0 ]]; then
  log "usage: $0 [--] COMMAND [ARGS...]"
  exit 2
fi

timeout_s="${RANKSLAM_VM_TIMEOUT_S:-240}"
memory_mb="${RANKSLAM_VM_MEMORY_MB:-1024}"
cpus="${RANKSLAM_VM_CPUS:-1}"
cpu_model="${RANKSLAM_VM_CPU:-max}"
vivid_opts="${RANKSLAM_VM_VIVID_OPTS:-n_devs=1}"

is_root() { [[ "$(id -u)" == 0 ]]; }
may_install() { is_root && [[ -z "${RANKSLAM_VM_NO_INSTALL:-}" ]]; }

apt_updated=""
apt_update_once() {
  if [[ -z "$apt_updated" ]]; then
    DEBIAN_FRONTEND=noninteractive apt-get update -qq >&2 || return 1
    apt_updated=1
  fi
}

busybox_is_static() {
  [[ -x /bin/busybox ]] && ! ldd /bin/busybox >/dev/null 2>&1
}

tools_present() {
  command -v qemu-system-x86_64 >/dev/null && busybox_is_static && command -v candump >/dev/null
}

# (1) Host tools: qemu, a static busybox for the initramfs, can-utils for the guest (chroot).
ensure_tools() {
  tools_present && return 0
  if ! may_install; then
    skip "qemu-system-x86_64, a static /bin/busybox and candump are needed (apt-get install ${kPackages[*]})"
  fi
  log "installing ${kPackages[*]}"
  if ! DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends "${kPackages[@]}" >&2; then
    apt_update_once || true
    DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends "${kPackages[@]}" >&2 ||
      skip "apt-get install ${kPackages[*]} failed"
  fi
  tools_present || skip "still missing qemu-system-x86_64, static busybox or candump after installing"
}

pick_cache_dir() {
  if [[ -n "${RANKSLAM_VM_CACHE:-}" ]]; then
    cache_dir="$RANKSLAM_VM_CACHE"
  elif mkdir -p /var/cache/rankslam/vm 2>/dev/null && [[ -w /var/cache/rankslam/vm ]]; then
    cache_dir=/var/cache/rankslam/vm
  else
    cache_dir="${XDG_CACHE_HOME:-$HOME/.cache}/rankslam/vm"
  fi
  mkdir -p "$cache_dir" || skip "cannot create the kernel cache $cache_dir"
}

kernel_package_name() {
  if [[ -n "${RANKSLAM_VM_KERNEL_PKG:-}" ]]; then
    echo "$RANKSLAM_VM_KERNEL_PKG"
    return 0
  fi
  local name
  name="$(apt-cache depends linux-image-amd64 2>/dev/null |
          awk '/Depends: linux-image-[0-9]/ { print $2; exit }')"
  if [[ -z "$name" ]] && is_root && [[ -z "${RANKSLAM_VM_NO_INSTALL:-}" ]]; then
    apt_update_once || true
    name="$(apt-cache depends linux-image-amd64 2>/dev/null |
            awk '/Depends: linux-image-[0-9]/ { print $2; exit }')"
  fi
  echo "$name"
}

# Unpacks the kernel package into $cache_dir/<package> and indexes its modules. Runs under the
# cache lock; a finished entry holds the file 'ready'.
fetch_kernel() {
  local package="$1" entry="$cache_dir/$1"
  [[ -f "$entry/ready" ]] && return 0
  local work
  work="$(mktemp -d "$cache_dir/.fetch.XXXXXX")"
  chmod 755 "$work"  # apt-get download drops privileges to _apt when it can write here
  log "downloading $package"
  if ! (cd "$work" && apt-get download "$package" >&2); then
    rm -rf "$work"
    return 1
  fi
  dpkg -x "$work"/*.deb "$work/root" || { rm -rf "$work"; return 1; }
  local ver
  ver="$(ls "$work/root/lib/modules" | head -n 1)"
  [[ -n "$ver" && -f "$work/root/boot/vmlinuz-$ver" ]] || { rm -rf "$work"; return 1; }
  # Bookworm ships plain .ko files; newer kernels compress them, which insmod cannot read.
  find "$work/root/lib/modules/$ver" -name '*.ko.xz' -exec xz -d {} + 2>/dev/null || true
  find "$work/root/lib/modules/$ver" -name '*.ko.zst' -exec zstd -q -d --rm {} + 2>/dev/null || true
  busybox depmod -b "$work/root" "$ver" || { rm -rf "$work"; return 1; }
  rm -rf "$entry"
  mkdir -p "$entry"
  mv "$work/root/boot/vmlinuz-$ver" "$entry/vmlinuz"
  mv "$work/root/lib/modules/$ver" "$entry/modules"
  echo "$ver" > "$entry/version"
  rm -rf "$work"
  touch "$entry/ready"
  log "cached kernel $ver in $entry"
  # Older kernels are not used again once a newer one is cached.
  local old
  for old in "$cache_dir"/linux-image-*; do
    [[ "$old" != "$entry" ]] && rm -rf "$old"
  done
  return 0
}

# (1b) The kernel: the version linux-image-amd64 depends on, else any kernel cached before.
ensure_kernel() {
  pick_cache_dir
  exec 9>"$cache_dir/.lock"
  flock 9
  local package
  package="$(kernel_package_name)"
  kernel_dir=""
  if [[ -n "$package" ]] && fetch_kernel "$package"; then
    kernel_dir="$cache_dir/$package"
  else
    local candidate
    for candidate in "$cache_dir"/linux-image-*; do
      [[ -f "$candidate/ready" ]] && kernel_dir="$candidate"
    done
    [[ -n "$kernel_dir" ]] || skip "no kernel package could be downloaded (apt-get download ${package:-linux-image-<ver>-amd64}) and none is cached in $cache_dir"
    log "could not fetch ${package:-the current kernel}; using the cached $(basename "$kernel_dir")"
  fi
  flock -u 9
  exec 9>&-
  kernel_version="$(cat "$kernel_dir/version")"
}

# Module paths (relative to the modules dir) in load order: dependencies first.
resolve_modules() {
  local dep_file="$kernel_dir/modules/modules.dep"
  awk -v roots="${kRootModules[*]}" '
    function norm(s) { gsub(/-/, "_", s); return s }
    function base(path,  b) { b = path; sub(/.*\//, "", b); sub(/\.ko$/, "", b); return norm(b) }
    function visit(path,  n, parts, i) {
      if (path in seen) return
      seen[path] = 1
      n = split(deps[path], parts, " ")
      # modules.dep lists dependencies deepest last; any order that visits all of them first works.
      for (i = n; i >= 1; --i) visit(parts[i])
      print path
    }
    {
      path = $1; sub(/:$/, "", path)
      line = $0; sub(/^[^:]*:[ ]*/, "", line)
      deps[path] = line
      by_name[base(path)] = path
    }
    END {
      n = split(roots, names, " ")
      for (i = 1; i <= n; ++i) {
        name = norm(names[i])
        if (!(name in by_name)) { print "missing module " names[i] > "/dev/stderr"; exit 1 }
        visit(by_name[name])
      }
    }' "$dep_file"
}

# (2) The initramfs: busybox, the modules and /init.
build_initramfs() {
  local root="$run_dir/initramfs"
  mkdir -p "$root"/{bin,dev,proc,sys,host,lib/modules}
  cp /bin/busybox "$root/bin/busybox"
  local modules
  modules="$(resolve_modules)" || fail "cannot resolve the kernel modules ${kRootModules[*]} in $kernel_dir"
  local path
  : > "$root/modules.order"
  while read -r path; do
    mkdir -p "$root/lib/modules/$(dirname "$path")"
    cp "$kernel_dir/modules/$path" "$root/lib/modules/$path"
    echo "$path" >> "$root/modules.order"
  done <<< "$modules"
  cat > "$root/init" <<EOF
#!/bin/busybox sh
/bin/busybox --install -s /bin
export PATH=/bin:/sbin
mount -t proc proc /proc
mount -t sysfs sysfs /sys
mount -t devtmpfs devtmpfs /dev
for m in \$(cat /modules.order); do
  opts=""
  case "\$m" in */vivid.ko) opts="$vivid_opts" ;; esac
  insmod "/lib/modules/\$m" \$opts || echo "rankslam-vm: insmod \$m failed"
done
ip link add dev vcan0 type vcan && ip link set vcan0 up || echo "rankslam-vm: vcan0 set-up failed"
rc=$kVmFailure
# cache=loose: the host root is read-only and unchanged while the VM runs, so the guest keeps
# its pages; the test binaries and their libraries load much faster.
if mount -t 9p -o trans=virtio,version=9p2000.L,ro,msize=262144,cache=loose host /host; then
  mkdir -p /out
  mount -t 9p -o trans=virtio,version=9p2000.L,msize=262144 out /out
  mount -t proc proc /host/proc
  mount -t sysfs sysfs /host/sys
  mount -t devtmpfs devtmpfs /host/dev
  mount -t tmpfs tmpfs /host/run
  mkdir -p /host/run/rankslam-vm /host/run/tmp
  mount -o bind /out /host/run/rankslam-vm
  # A writable /tmp, unless the command itself lives under the host's /tmp.
  [ -e /out/keep-host-tmp ] || mount -t tmpfs tmpfs /host/tmp
  echo "rankslam-vm: kernel \$(uname -r) up \$(cut -d' ' -f1 /proc/uptime) s, running the command"
  chroot /host /bin/sh /run/rankslam-vm/command.sh
  rc=\$?
  echo "\$rc" > /out/exit-code
  sync
else
  echo "rankslam-vm: cannot mount the host root over 9p"
fi
echo "$kResultTag exit=\$rc"
poweroff -f
EOF
  chmod 755 "$root/init"
  (cd "$root" && find . | busybox cpio -o -H newc 2>/dev/null | gzip -1) > "$run_dir/initramfs.cpio.gz"
}

# The command, quoted for the guest's shell, with the environment it needs.
write_command() {
  local out="$run_dir/out"
  mkdir -p "$out"
  {
    echo "export RANKSLAM_VM=1 RANKSLAM_VM_OUT=/run/rankslam-vm/files LC_ALL=C"
    echo "export TMPDIR=/run/tmp HOME=/run/tmp"
    echo "export PATH=/usr/local/sbin:/usr/local/bin:/usr/sbin:/usr/bin:/sbin:/bin"
    local var
    while IFS= read -r var; do
      printf 'export %s=%q\n' "$var" "${!var}"
    done < <(compgen -v | grep '^GTEST_' || true)
    echo "mkdir -p \"\$RANKSLAM_VM_OUT\""
    printf 'cd %q 2>/dev/null || cd /\n' "$PWD"
    local arg
    for arg in "$PWD" "$@"; do
      [[ "$arg" == /tmp || "$arg" == /tmp/* ]] && touch "$out/keep-host-tmp"
    done
    printf 'exec'
    printf ' %q' "$@"
    printf '\n'
  } > "$out/command.sh"
}

# (2b) The accelerator. /dev/kvm can exist where KVM does not work (nested virtualisation that
# aborts or spins in the host kernel), so a tiny initramfs is booted under KVM first.
pick_accel() {
  accel_args=(-accel tcg -cpu "$cpu_model")
  local wanted="${RANKSLAM_VM_ACCEL:-auto}"
  case "$wanted" in
    tcg) return 0 ;;
    kvm) accel_args=(-accel kvm -cpu host); return 0 ;;
    auto) ;;
    *) fail "RANKSLAM_VM_ACCEL=$wanted: expected kvm, tcg or auto" ;;
  esac
  if [[ ! -r /dev/kvm || ! -w /dev/kvm ]]; then
    log "no usable /dev/kvm: TCG"
    return 0
  fi
  local qemu_version
  qemu_version="$(qemu-system-x86_64 --version | head -n 1 | tr -c 'A-Za-z0-9.\n' '_')"
  local verdict="$cache_dir/kvm-$(uname -r)-$qemu_version"
  if [[ ! -f "$verdict" ]]; then
    local probe="$run_dir/kvm-probe"
    mkdir -p "$probe/root/bin" "$probe/root/dev" "$probe/root/proc"
    cp /bin/busybox "$probe/root/bin/busybox"
    printf '#!/bin/busybox sh\n/bin/busybox mount -t devtmpfs devtmpfs /dev\n/bin/busybox echo %s > /dev/ttyS0\n/bin/busybox poweroff -f\n' \
      "RANKSLAM-KVM-PROBE-OK" > "$probe/root/init"
    chmod 755 "$probe/root/init"
    (cd "$probe/root" && find . | busybox cpio -o -H newc 2>/dev/null | gzip -1) > "$probe/initramfs.cpio.gz"
    local result=tcg
    if timeout -k 5 30 qemu-system-x86_64 -accel kvm -cpu host -m 256 -nographic -no-reboot -nodefaults \
         -serial stdio -monitor none -kernel "$kernel_dir/vmlinuz" -initrd "$probe/initramfs.cpio.gz" \
         -append "console=ttyS0 quiet panic=-1" < /dev/null 2>&1 | grep -aq "RANKSLAM-KVM-PROBE-OK"; then
      result=kvm
    fi
    echo "$result" > "$verdict"
  fi
  if [[ "$(cat "$verdict")" == kvm ]]; then
    accel_args=(-accel kvm -cpu host)
    log "KVM"
  else
    log "KVM does not work on this host (the probe boot did not finish; $verdict): TCG"
  fi
}

# (3) Boot, stream the console, take the exit code from the result line.
run_vm() {
  local log_file="$run_dir/console.log"
  local start_s=$SECONDS
  set +e
  timeout -k 10 "$timeout_s" qemu-system-x86_64 "${accel_args[@]}" -m "$memory_mb" -smp "$cpus" \
      -nographic -no-reboot -nodefaults -serial stdio -monitor none \
      -kernel "$kernel_dir/vmlinuz" -initrd "$run_dir/initramfs.cpio.gz" \
      -append "console=ttyS0 quiet loglevel=3 panic=-1 oops=panic" \
      -virtfs local,path=/,mount_tag=host,security_model=none,readonly=on,multidevs=remap \
      -virtfs "local,path=$run_dir/out,mount_tag=out,security_model=none" \
      < /dev/null 2>&1 | sed -u -e 's/\r$//' -e 's/\x1b\[[0-9;?]*[A-Za-z]//g' -e 's/\x1bc//g' | tee "$log_file"
  local statuses=("${PIPESTATUS[@]}")
  set -e
  local elapsed_s=$((SECONDS - start_s))
  local line
  # Kernel messages may share the console line, so the tag is searched anywhere in it; the
  # file the guest wrote is the fallback for a garbled console.
  line="$(grep -ao "$kResultTag exit=[0-9]*" "$log_file" | tail -n 1 || true)"
  if [[ -z "$line" && -s "$run_dir/out/exit-code" ]]; then
    line="$kResultTag exit=$(tr -dc '0-9' < "$run_dir/out/exit-code")"
  fi
  if [[ -z "$line" ]]; then
    if [[ "${statuses[0]}" == 124 || "${statuses[0]}" == 137 ]]; then
      fail "the VM did not finish within ${timeout_s} s"
    fi
    fail "the VM stopped (qemu exit ${statuses[0]}) without printing '$kResultTag' after ${elapsed_s} s"
  fi
  local code="${line#*exit=}"
  [[ "$code" =~ ^[0-9]+$ ]] || fail "malformed result line '$line'"
  log "kernel $kernel_version, VM run ${elapsed_s} s, command exit code $code"
  if [[ -n "${RANKSLAM_VM_FILES_TO:-}" ]]; then
    mkdir -p "$RANKSLAM_VM_FILES_TO"
    cp -a "$run_dir/out/files/." "$RANKSLAM_VM_FILES_TO/" 2>/dev/null || true
  fi
  if [[ -n "$(ls -A "$run_dir/out/files" 2>/dev/null)" ]] && [[ "$code" != 0 || -n "${RANKSLAM_VM_KEEP:-}" ]]; then
    keep_dir=1
    log "files the command wrote: $run_dir/out/files"
  fi
  return "$code"
}

ensure_tools
ensure_kernel
run_dir="$(mktemp -d "${TMPDIR:-/tmp}/rankslam-vm.XXXXXX")"
keep_dir=""
cleanup() { [[ -n "$keep_dir" || -n "${RANKSLAM_VM_KEEP:-}" ]] || rm -rf "$run_dir"; }
trap cleanup EXIT
build_initramfs
pick_accel
write_command "$@"
set +e
run_vm
code=$?
set -e
exit "$code"
