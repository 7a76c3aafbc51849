#!/bin/sh
# Runs a command in a private network namespace holding only lo, with multicast routed to lo, so
# nothing it sends (LCM's IGMP joins included) can reach a real interface. Needs root
# (CAP_SYS_ADMIN); without it, says so and runs the command on the host's network.
#   in_private_net.sh COMMAND [ARG...]
if unshare -n true 2>/dev/null; then
  exec unshare -n sh -c 'ip link set lo up multicast on && ip route add 224.0.0.0/4 dev lo && exec "$@"' sh "$@"
fi
echo "note: no private network namespace; running on the host's network" >&2
exec "$@"
