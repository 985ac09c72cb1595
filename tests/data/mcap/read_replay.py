#!/usr/bin/env python3
"""Reads a railgrip replay MCAP with the official MCAP reader (pip install mcap) and prints
what tests/mcap_encodings.rs checks, as JSON: per topic the schema and message encodings, the
message count, the log times and every message's decoded JSON value.

    python3 tests/data/mcap/read_replay.py RUN.railgrip.mcap
"""

import json
import sys

from mcap.reader import make_reader


def main(path):
    topics = {}
    with open(path, "rb") as f:
        reader = make_reader(f)
        summary = reader.get_summary()
        for schema, channel, message in reader.iter_messages(log_time_order=True):
            t = topics.setdefault(
                channel.topic,
                {
                    "schema_name": schema.name,
                    "schema_encoding": schema.encoding,
                    "schema": json.loads(schema.data),
                    "message_encoding": channel.message_encoding,
                    "log_times": [],
                    "values": [],
                },
            )
            t["log_times"].append(message.log_time)
            (value,) = json.loads(message.data).values()
            t["values"].append(value)
    json.dump(
        {"message_count": summary.statistics.message_count, "topics": topics},
        sys.stdout,
    )


if __name__ == "__main__":
    main(sys.argv[1])
