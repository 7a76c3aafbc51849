#!/bin/bash
# Guest test: our SocketCAN transport on a real vcan0 — the live round trip (filters, kernel
# timestamps, no own echo) and the unit suite, whose open-error test takes its AF_CAN branch here.
# Args: SOCKETCAN_LIVE_VMTEST SOCKETCAN_TEST (the two gtest binaries from the build).
set -uo pipefail
here=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
# shellcheck source=lib.sh
. "$here/lib.sh"
live=$1
unit=$2
"$live" --gtest_brief=1 && pass "live round trip on vcan0" || fail "live round trip on vcan0"
"$unit" --gtest_brief=1 && pass "socketcan unit suite with AF_CAN present" || fail "socketcan unit suite"
echo "$passes passed, $fails failed"
((fails == 0))
