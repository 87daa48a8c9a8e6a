#!/bin/sh
# Two "machines" on one computer, as root: two network namespaces on a bridge, each with its
# own address and network stack, so what crosses between them is real multicast and real UDP.
# Runs `PROGRAM... 1` in the first and `PROGRAM... 2` in the second with the team's URL (url.sh),
# then removes them; exits 0 if both robots did. PREFIX (default `ay`) names what it creates.
#
#   sudo sh two_namespaces.sh target/debug/examples/tutorial_08_two_machines
#   sudo sh two_namespaces.sh python3 examples/tutorial/08_two_machines/main.py
set -eu
. "$(dirname "$0")/url.sh"
p=${PREFIX:-ay}
cleanup() {
    ip netns del "${p}robot1" 2>/dev/null || true
    ip netns del "${p}robot2" 2>/dev/null || true
    ip link del "$p-br" 2>/dev/null || true
}
trap cleanup EXIT
ip link add "$p-br" type bridge
ip link set "$p-br" up
for i in 1 2; do
    ip netns add "${p}robot$i"
    ip link add "$p-h$i" type veth peer name "$p-c$i"
    ip link set "$p-c$i" netns "${p}robot$i"
    ip link set "$p-h$i" master "$p-br"
    ip link set "$p-h$i" up
    ip -n "${p}robot$i" addr add "10.87.0.$i/24" dev "$p-c$i"
    ip -n "${p}robot$i" link set "$p-c$i" up
    ip -n "${p}robot$i" link set lo up
    ip -n "${p}robot$i" route add 224.0.0.0/4 dev "$p-c$i" # multicast leaves by that interface
done
status=0
ip netns exec "${p}robot1" "$@" 1 &
first=$!
ip netns exec "${p}robot2" "$@" 2 || status=1
wait "$first" || status=1
exit "$status"
