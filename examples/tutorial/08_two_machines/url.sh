# The team's URL, the same on every machine: discovery by multicast with a TTL of 1 so that it
# leaves the machine, and a fixed port so that tools can reach the robots by address.
export AYLLU_URL='udp://0.0.0.0:7400?discovery=239.255.65.89:7400&ttl=1'
