# The team's URL, the same on every machine: discovery by multicast with a TTL of 1, so that it
# leaves the machine; port 0, so that each program (the robot's, the tools) binds its own.
export AYLLU_URL='udp://0.0.0.0:0?discovery=239.255.65.89:7390&ttl=1'
