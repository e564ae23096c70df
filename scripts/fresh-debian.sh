#!/usr/bin/env bash
# SPDX-License-Identifier: Apache-2.0
# Runs a command as on the README's fresh Debian 12 machine: a minimal Debian 12
# (debootstrap --variant=minbase: apt and bash, none of Crisp's packages) in a
# new folder, a clone of this repository's HEAD in it at /root/crisp, and the
# command run there as root by chroot, with this machine's /proc, /sys and /dev
# and an empty environment. Checks that the two set-up commands install all
# they need themselves, which a machine with the packages already on it cannot.
# Needs root, debootstrap and access to deb.debian.org.
# Usage: scripts/fresh-debian.sh DIR COMMAND...
#   e.g. scripts/fresh-debian.sh /tmp/fresh bash scripts/main-job.sh
#        scripts/fresh-debian.sh /tmp/fresh2 bash .ci/run
# DIR must not exist. It is kept afterwards, with nothing mounted in it (the
# clone's out/ and build*/ are in DIR/root/crisp); remove it with rm -rf only
# after checking that `grep DIR /proc/self/mountinfo` finds nothing.
set -euo pipefail
if (($# < 2)); then
  sed -n '10,15p' "$0" >&2
  exit 2
fi
dir=$1
shift
[ "$(id -u)" = 0 ] || { echo "fresh-debian: needs root (chroot, mount)" >&2; exit 2; }
command -v debootstrap >/dev/null || { echo "fresh-debian: needs debootstrap (apt-get install debootstrap)" >&2; exit 2; }
[ ! -e "$dir" ] || { echo "fresh-debian: $dir exists; give a new folder" >&2; exit 2; }
repo=$(git -C "$(dirname "$0")" rev-parse --show-toplevel)
mirror=http://deb.debian.org/debian

mkdir -p "$dir"
root=$(realpath "$dir")/root
debootstrap --variant=minbase bookworm "$root" "$mirror" >"$dir/debootstrap.log" 2>&1 ||
  { echo "fresh-debian: debootstrap failed (log: $dir/debootstrap.log)" >&2; exit 1; }
# The sources of a Debian 12 installation, with its updates and security fixes.
cat >"$root/etc/apt/sources.list" <<EOF
deb $mirror bookworm main
deb $mirror bookworm-updates main
deb http://deb.debian.org/debian-security bookworm-security main
EOF
cp /etc/resolv.conf "$root/etc/resolv.conf"
git clone -q "$repo" "$root/root/crisp"

# shellcheck disable=SC2317  # called by the EXIT trap
unmount() {
  for m in dev sys proc; do
    if mountpoint -q "$root/$m"; then umount -R "$root/$m" || umount -R -l "$root/$m"; fi
  done
}
trap unmount EXIT
mount -t proc proc "$root/proc"
# rslave: unmounting the copies later leaves this machine's own mounts alone.
for m in sys dev; do
  mount --rbind "/$m" "$root/$m"
  mount --make-rslave "$root/$m"
done

echo "fresh-debian: running '$*' in $root/root/crisp ($(git -C "$repo" rev-parse --short HEAD))" >&2
rc=0
chroot "$root" /usr/bin/env -i HOME=/root TERM=dumb PATH=/usr/local/sbin:/usr/local/bin:/usr/sbin:/usr/bin:/sbin:/bin \
  bash -c 'cd /root/crisp && "$@"' fresh-debian "$@" || rc=$?
echo "fresh-debian: exit status $rc; the clone is $root/root/crisp" >&2
exit "$rc"
