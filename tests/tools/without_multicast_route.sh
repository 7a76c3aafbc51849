#!/bin/sh
# Runs a command in a network namespace holding only lo, up, with no route for multicast: a cab
# controller whose only interface is lo (docs/guides/install.md#lcm-route). Needs root
# (CAP_SYS_ADMIN); without it exits 77, which CTest takes as skipped (SKIP_RETURN_CODE).
#   without_multicast_route.sh COMMAND [ARG...]
if unshare -n true 2>/dev/null; then
  exec unshare -n sh -c 'ip link set lo up && exec "$@"' sh "$@"
fi
echo "skipped: no private network namespace (not root)" >&2
exit 77
