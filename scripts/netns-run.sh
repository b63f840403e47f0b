#!/usr/bin/env bash
# Runs a command where 127.0.0.2 and 127.0.0.3 are local addresses (a rig of
# camsim-gige cameras needs one loopback address per camera): directly if the
# host has them, else in a private network namespace (unshare -rn: a user
# namespace, no root needed) whose lo carries them. Exit 77 (ctest: skipped)
# if neither is possible.
#   scripts/netns-run.sh COMMAND [ARG...]
set -euo pipefail
have() { ip -4 -o addr show dev lo 2>/dev/null | grep -q "inet $1/"; }
if have 127.0.0.2 && have 127.0.0.3; then exec "$@"; fi
if ! command -v unshare >/dev/null || ! command -v ip >/dev/null; then
  echo "netns-run: needs unshare (util-linux) and ip (iproute2) for 127.0.0.2/.3; skipped" >&2
  exit 77
fi
if ! unshare -rn true 2>/dev/null; then
  echo "netns-run: cannot create a network namespace (unshare -rn); skipped" >&2
  exit 77
fi
exec unshare -rn sh -c 'ip link set lo up && ip addr add 127.0.0.2/8 dev lo && ip addr add 127.0.0.3/8 dev lo && exec "$@"' sh "$@"
