"""A Foxglove WebSocket client, written from the protocol (foxglove.websocket.v1), for the live
test of `ayllu foxglove` (crates/ayllu-cli/tests/tool/foxglove.rs).

It connects offering the protocol's subprotocols: `foxglove.sdk.v1`, the name the Foxglove SDK
0.30 gives the v1 protocol (the only one it accepts of the two), and `foxglove.websocket.v1`,
the name older servers use; the messages are the same. It reads the server's `serverInfo` and `advertise`
messages, subscribes to the channels of the topics it is given as soon as they are
advertised, and prints one JSON line per message received on them:
`{"topic": T, "log_time": NS, "message": {...}}` (message data frames: opcode 1, a
little-endian u32 subscription id, a u64 log time, then the payload, JSON here).

The Foxglove SDK 0.30.3 sends an `advertise` before it records the channel as advertised to
the client, so a client that subscribes at once can be told `Unknown channel ID: N` (a
status); the subscription is then sent again, up to RESUBSCRIBE times per channel.

Usage: foxglove_ws_client.py WS_URL --topic T [--topic T2] [--seconds S] [--count N]
It stops after S seconds (default 60) or N messages in all; exit code 0 if at least one message
arrived, 1 otherwise. The first line is `{"server": NAME, "subprotocol": P}`.
"""

import argparse
import json
import struct
import sys
import time

from websockets.sync.client import connect

SUBPROTOCOLS = ["foxglove.sdk.v1", "foxglove.websocket.v1"]
MESSAGE_DATA = 0x01
RESUBSCRIBE = 20


def emit(obj):
    print(json.dumps(obj), flush=True)


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("url")
    parser.add_argument("--topic", action="append", required=True)
    parser.add_argument("--seconds", type=float, default=60.0)
    parser.add_argument("--count", type=int, default=0)
    args = parser.parse_args()

    wanted = set(args.topic)
    deadline = time.monotonic() + args.seconds
    subscribed = {}  # subscription id -> topic
    by_channel = {}  # channel id -> subscription id
    retries = {}  # channel id -> subscriptions sent again
    next_sub = 1
    received = 0
    with connect(
        args.url, subprotocols=SUBPROTOCOLS, open_timeout=10, max_size=None
    ) as ws:
        while time.monotonic() < deadline:
            try:
                frame = ws.recv(timeout=max(0.01, deadline - time.monotonic()))
            except TimeoutError:
                break
            if isinstance(frame, str):
                op = json.loads(frame)
                if op.get("op") == "status":
                    print(json.dumps(op), file=sys.stderr, flush=True)
                    text = op.get("message", "")
                    if text.startswith("Unknown channel ID: "):
                        channel = int(text.rsplit(" ", 1)[1])
                        sub = by_channel.get(channel)
                        if sub is not None and retries.get(channel, 0) < RESUBSCRIBE:
                            retries[channel] = retries.get(channel, 0) + 1
                            time.sleep(0.05)
                            one = {"id": sub, "channelId": channel}
                            ws.send(
                                json.dumps({"op": "subscribe", "subscriptions": [one]})
                            )
                elif op.get("op") == "serverInfo":
                    emit({"server": op.get("name"), "subprotocol": ws.subprotocol})
                elif op.get("op") == "advertise":
                    subs = []
                    for ch in op["channels"]:
                        if (
                            ch["topic"] in wanted
                            and ch["topic"] not in subscribed.values()
                        ):
                            subscribed[next_sub] = ch["topic"]
                            by_channel[ch["id"]] = next_sub
                            subs.append({"id": next_sub, "channelId": ch["id"]})
                            emit(
                                {
                                    "subscribed": ch["topic"],
                                    "schemaName": ch.get("schemaName"),
                                }
                            )
                            next_sub += 1
                    if subs:
                        ws.send(json.dumps({"op": "subscribe", "subscriptions": subs}))
                continue
            if not frame or frame[0] != MESSAGE_DATA:
                continue
            sub_id, log_time = struct.unpack_from("<IQ", frame, 1)
            topic = subscribed.get(sub_id)
            if topic is None:
                continue
            emit(
                {
                    "topic": topic,
                    "log_time": log_time,
                    "message": json.loads(frame[13:]),
                }
            )
            received += 1
            if args.count and received >= args.count:
                break
    return 0 if received else 1


if __name__ == "__main__":
    sys.exit(main())
