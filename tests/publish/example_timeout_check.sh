#!/bin/sh
# The example readers when nothing arrives (run it in a private network namespace: in_private_net.sh,
# where nothing publishes): each keeps its documented exit status (docs/guides/dds-lcm.md#the-examples:
# 3 when the timeout comes before what was asked for, 0 at the timeout of a plain watch) and says
# on stderr what it waited for — topic or channels, domain, partition, network or URL — and the
# likely cause: `oegw demo` publishes under its own names (partition oegw-demo, channels
# OEGW_DEMO_*), which a reader left at a gateway's defaults does not hear, naming the option that
# does. A reader already on the demo's names asks whether the demo runs.
#   example_timeout_check.sh EXAMPLES_DIR
set -u
ex=$1
dir=$(mktemp -d)
trap 'rm -rf "$dir"' EXIT
fails=0
# expect RC TEXT... -- PROGRAM ARG...: exit RC, "ready" on stdout and every TEXT (fixed) on stderr.
expect() {
  want_rc=$1
  shift
  n=0
  while [ "$1" != -- ]; do n=$((n + 1)); eval "want_$n=\$1"; shift; done
  shift
  timeout 20 "$@" >"$dir/out" 2>"$dir/err"
  rc=$?
  ok=1
  [ "$rc" -eq "$want_rc" ] || ok=0
  [ "$(cat "$dir/out")" = ready ] || ok=0
  i=0
  while [ $i -lt $n ]; do
    i=$((i + 1)); t=''; eval "t=\$want_$i"
    grep -qF -- "$t" "$dir/err" || { ok=0; echo "  missing on stderr: $t" >&2; }
  done
  if [ $ok -eq 1 ]; then
    # The command line after the program: dash strips $1 off "$*", the words joined.
    # shellcheck disable=SC3058
    echo "ok: $(basename "$1") ${*#"$1"} -> $rc; $(head -1 "$dir/err")"
  else
    fails=$((fails + 1))
    echo "FAILED: $* -> exit $rc (expected $want_rc); stdout: $(cat "$dir/out"); stderr:" >&2
    sed 's/^/    /' "$dir/err" >&2
  fi
}
url='udpm://224.0.0.1:7667?ttl=0'
expect 3 "dds_subscriber: nothing on oegw/joystick within 1 s (domain 0, partition oegw, network loopback)" \
  "dds_subscriber: the demo publishes partition oegw-demo: --partition oegw-demo" \
  -- "$ex/dds_subscriber" --count 10 --timeout 1 --partition oegw --network loopback
expect 0 "dds_subscriber: nothing on oegw/joystick within 1 s (domain 7, partition oegw-demo, network loopback)" \
  "is \`oegw demo\` running" -- "$ex/dds_subscriber" --timeout 1 --partition oegw-demo --domain 7
expect 3 "dds_status: nothing on oegw/status within 1 s (domain 0, partition oegw, network loopback)" \
  "--partition oegw-demo" -- "$ex/dds_status" --timeout 1
expect 0 "lcm_subscriber: nothing on the channels matching OEGW_JOYSTICK_[0-9]+ within 1 s (URL $url)" \
  "lcm_subscriber: the demo publishes channels OEGW_DEMO_*: --channel 'OEGW_DEMO_JOYSTICK_[0-9]+'" \
  -- "$ex/lcm_subscriber" --url "$url" --channel 'OEGW_JOYSTICK_[0-9]+' --timeout 1
expect 3 "lcm_subscriber: nothing on the channels matching OEGW_DEMO_STATUS within 1 s (URL $url)" \
  "is \`oegw demo\` running" -- "$ex/lcm_subscriber" --channel OEGW_DEMO_STATUS --count 1 --timeout 1
expect 3 "lcm_status: nothing on the channels matching OEGW_STATUS within 1 s (URL $url)" \
  "lcm_status: the demo publishes channels OEGW_DEMO_*: --prefix OEGW_DEMO_" -- "$ex/lcm_status" --timeout 1
[ "$fails" -eq 0 ] || { echo "$fails failed"; exit 1; }
