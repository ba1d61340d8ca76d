# Sourced by the tests that run roomfix on several simulated hosts
# (multi_host_test.sh, hall_test.sh): network namespaces, each with its own
# hostname (UTS namespace) and one veth cable to a Linux bridge, 224.0.0.0/4
# routed to the veth, as a real host without a default route needs. Nothing
# leaves this machine: the namespaces are private (user + net + mount + UTS,
# no root needed).
#
# The sourcing script sets `test_name` (its messages' prefix) first, then:
#   enter_private_namespaces "$@"   re-runs the script inside the namespaces
#   make_work_dir                   $work, killed $pids and a cleanup trap
#   make_bridged_hosts 10.77.0 camera radio solver   (addresses .1, .2, ...)
#   on_host HOST CMD... &           runs CMD on HOST under its own hostname

skip() {
  echo "$test_name: skipped: $*" >&2
  exit 77
}
fail() {
  echo "$test_name: FAILED: $*" >&2
  exit 1
}

# Exits 77 (ctest's skip code) with one line when this machine does not allow
# the namespaces.
enter_private_namespaces() {
  if [[ "${ROOMFIX_BRIDGED_HOSTS_INNER:-}" == "1" ]]; then return; fi
  unshare -rnmu true 2>/dev/null ||
    skip "cannot create user + network + mount + UTS namespaces (unshare -rnmu failed)"
  exec unshare -rnmu env ROOMFIX_BRIDGED_HOSTS_INNER=1 "$0" "$@"
}

# The processes' stderr and the log stay in $work when the test fails (or
# with ROOMFIX_KEEP_TEMP=1); every pid in $pids is killed on exit.
make_work_dir() {
  work=$(mktemp -d "${TMPDIR:-/tmp}/roomfix_$test_name.XXXXXX")
  pids=()
  trap cleanup_work_dir EXIT
}
cleanup_work_dir() {
  local rc=$? pid
  for pid in "${pids[@]}"; do kill -KILL "$pid" 2>/dev/null || true; done
  wait 2>/dev/null || true
  if [[ "${ROOMFIX_KEEP_TEMP:-}" == "1" ]] || ((rc != 0 && rc != 77)); then
    echo "$test_name: kept $work" >&2
  else
    rm -rf "$work"
  fi
}

# make_bridged_hosts PREFIX HOST...: host k (from 1) gets PREFIX.k/24.
make_bridged_hosts() {
  local prefix=$1 n=1 h
  shift
  # `ip netns add` needs a writable /run/netns: a private tmpfs on /run (this
  # mount namespace only).
  mount -t tmpfs roomfix_run /run 2>/dev/null || skip "cannot mount a private /run"
  mkdir -p /run/netns
  ip link set lo up
  ip link add br0 type bridge 2>/dev/null || skip "cannot create a bridge (no bridge module?)"
  ip link set br0 up
  for h in "$@"; do
    ip netns add "$h" 2>/dev/null || skip "ip netns add failed"
    ip link add "v-$h" type veth peer name "lan-$h" 2>/dev/null || skip "cannot create veth pairs"
    ip link set "v-$h" master br0
    ip link set "v-$h" up
    ip link set "lan-$h" netns "$h"
    ip -n "$h" link set lo up
    ip -n "$h" link set "lan-$h" name eth0
    ip -n "$h" addr add "$prefix.$n/24" dev eth0
    ip -n "$h" link set eth0 up
    ip -n "$h" link set eth0 multicast on
    ip -n "$h" route add 224.0.0.0/4 dev eth0
    n=$((n + 1))
  done
}

# Call it in the background (`on_host H CMD... &`): the subshell becomes the
# command, so $! is its pid and signals reach it.
on_host() {
  local h=$1
  shift
  exec ip netns exec "$h" unshare -u sh -c 'hostname "$0"; exec "$@"' "roomfix-$h" "$@"
}
