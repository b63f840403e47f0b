#!/usr/bin/env bash
# Runs a command in a private network namespace (unshare -rn: a user
# namespace, no root needed) with a veth pair on one subnet: v0 10.9.0.1/24
# and v1 10.9.0.2/24, broadcast 10.9.0.255. Unlike loopback it carries
# broadcast, so a camera on 10.9.0.1 gets what a client on 10.9.0.2 sends to
# 10.9.0.255. Exit 77 (ctest: skipped) if the namespace or the pair cannot
# be made.
#   scripts/netns-veth-run.sh COMMAND [ARG...]
set -euo pipefail
if ! command -v unshare >/dev/null || ! command -v ip >/dev/null; then
  echo "netns-veth-run: needs unshare (util-linux) and ip (iproute2); skipped" >&2
  exit 77
fi
setup='ip link set lo up &&
  ip link add v0 type veth peer name v1 &&
  ip addr add 10.9.0.1/24 brd + dev v0 && ip addr add 10.9.0.2/24 brd + dev v1 &&
  ip link set v0 up && ip link set v1 up'
if ! unshare -rn sh -c "$setup" 2>/dev/null; then
  echo "netns-veth-run: cannot make a network namespace with a veth pair; skipped" >&2
  exit 77
fi
exec unshare -rn sh -c "$setup"' && exec "$@"' sh "$@"
