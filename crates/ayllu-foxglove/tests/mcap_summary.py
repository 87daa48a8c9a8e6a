"""Reads an MCAP file with the `mcap` package (the reference Python reader, not the writer's
own code) and prints one JSON object: the header's profile, and per topic the schema name, the
schema and message encodings, the message count and the first JSON message (for JSON
channels), with the log times in order.

Usage: mcap_summary.py FILE. Used by crates/ayllu-cli/tests/tool/foxglove.rs.
"""

import json
import sys

from mcap.reader import make_reader


def main():
    with open(sys.argv[1], "rb") as f:
        reader = make_reader(f)
        header = reader.get_header()
        topics = {}
        in_order = True
        last = -1
        for schema, channel, message in reader.iter_messages(log_time_order=False):
            t = topics.setdefault(
                channel.topic,
                {
                    "schema": schema.name if schema else None,
                    "schema_encoding": schema.encoding if schema else None,
                    "message_encoding": channel.message_encoding,
                    "count": 0,
                    "first": None,
                },
            )
            t["count"] += 1
            if t["first"] is None and channel.message_encoding == "json":
                t["first"] = json.loads(message.data)
            if message.log_time < last:
                in_order = False
            last = message.log_time
        print(
            json.dumps(
                {"profile": header.profile, "in_order": in_order, "topics": topics}
            )
        )


if __name__ == "__main__":
    main()
