#!/usr/bin/env python3
"""Reads an MCAP file host-bench wrote with Python's `mcap` package, an implementation of the
format that is not ours: every channel's schema and encoding, every message decoded as JSON
with the fields its JSON schema requires, log times never going back, and the summary's counts
equal to the messages read. Prints a line per channel; exits 1 on any difference.

    scripts/mcap-check.py FILE [--expect TOPIC=N ...] [--topics T1,T2,...]
"""

import argparse
import json
import sys

from mcap.reader import make_reader


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("file")
    ap.add_argument("--topics", help="the channels the file must have, comma separated")
    ap.add_argument("--expect", action="append", default=[], help="TOPIC=N messages")
    a = ap.parse_args()
    errors = []
    with open(a.file, "rb") as f:
        reader = make_reader(f)
        summary = reader.get_summary()
        counts, last = {}, 0
        for schema, channel, message in reader.iter_messages(log_time_order=False):
            if message.log_time < last:
                errors.append(f"{channel.topic}: log time {message.log_time} after {last}")
            last = message.log_time
            if schema.encoding != "jsonschema" or channel.message_encoding != "json":
                errors.append(f"{channel.topic}: {schema.encoding}/{channel.message_encoding}")
            fields = json.loads(schema.data).get("required", [])
            body = json.loads(message.data)
            missing = [k for k in fields if k not in body]
            if missing and len(errors) < 20:
                errors.append(f"{channel.topic}: a message at {message.log_time} ns lacks {missing}")
            counts[channel.topic] = counts.get(channel.topic, 0) + 1
    stats = summary.statistics.channel_message_counts
    for cid, ch in sorted(summary.channels.items()):
        schema = summary.schemas[ch.schema_id].name
        n = counts.get(ch.topic, 0)
        print(f"{ch.topic:28} {schema:26} {n:6} messages")
        if stats.get(cid, 0) != n:
            errors.append(f"{ch.topic}: the summary counts {stats.get(cid, 0)}, read {n}")
    topics = {ch.topic for ch in summary.channels.values()}
    for t in (a.topics.split(",") if a.topics else []):
        if t not in topics:
            errors.append(f"no channel {t}")
    for e in a.expect:
        t, n = e.rsplit("=", 1)
        if counts.get(t, 0) != int(n):
            errors.append(f"{t}: {counts.get(t, 0)} messages, expected {n}")
    print(f"{a.file}: {sum(counts.values())} messages, last log time {last / 1e9:.3f} s")
    for e in errors:
        print("error:", e, file=sys.stderr)
    sys.exit(1 if errors else 0)


if __name__ == "__main__":
    main()
