#!/usr/bin/env python3
"""Reads a flight recording with the `mcap` package from PyPI (nobody at deckwatch wrote it) and
prints what it found as JSON: per channel its schema, encodings and message count; the metadata
and attachments; whether the file has a summary; and, for a file a killed recorder left (no
summary), how many messages a streaming read gets before the file ends.

Usage: mcap_check.py FILE.mcap
"""
import json
import sys

from mcap.reader import NonSeekingReader, make_reader


def log_text(data):
    """The `message` (field 3) of a foxglove.Log, read from the protobuf wire format by hand
    (no generated classes needed): a test that misses a line can then say which."""
    i = 0

    def varint():
        nonlocal i
        value, shift = 0, 0
        while True:
            b = data[i]
            i += 1
            value |= (b & 0x7F) << shift
            shift += 7
            if b < 0x80:
                return value

    while i < len(data):
        key = varint()
        field, wire = key >> 3, key & 7
        if wire == 0:
            varint()
        elif wire == 1:
            i += 8
        elif wire == 5:
            i += 4
        elif wire == 2:
            n = varint()
            chunk = data[i : i + n]
            i += n
            if field == 3:
                return chunk.decode("utf-8", "replace")
        else:
            break
    return ""


def main(path):
    out = {"channels": {}, "metadata": {}, "attachments": [], "summary": False}
    with open(path, "rb") as f:
        reader = make_reader(f)
        summary = None
        try:
            summary = reader.get_summary()
        except Exception as e:  # a cut file
            out["summary_error"] = str(e)
        if summary is not None and summary.statistics is not None:
            out["summary"] = True
            for cid, ch in summary.channels.items():
                schema = summary.schemas[ch.schema_id]
                out["channels"][ch.topic] = {
                    "schema": schema.name,
                    "schema_encoding": schema.encoding,
                    "message_encoding": ch.message_encoding,
                    "count": summary.statistics.channel_message_counts.get(cid, 0),
                }
            for m in reader.iter_metadata():
                out["metadata"][m.name] = dict(m.metadata)
            for a in reader.iter_attachments():
                out["attachments"].append({"name": a.name, "media_type": a.media_type, "bytes": len(a.data)})
            # Every message decodes as its encoding says: JSON parses, protobuf is left to the
            # schema (its bytes are counted).
            counted = {}
            first = {}
            log_lines = []
            for schema, channel, message in reader.iter_messages():
                counted[channel.topic] = counted.get(channel.topic, 0) + 1
                if channel.message_encoding == "json":
                    value = json.loads(message.data)
                    first.setdefault(channel.topic, value)
                elif schema.name == "foxglove.Log":
                    log_lines.append(log_text(message.data))
            out["iterated"] = counted
            out["log_lines"] = log_lines
            out["first_json"] = {t: sorted(v.keys()) for t, v in first.items()}
    # A streaming read, as of a file still being written or cut.
    streamed = {}
    with open(path, "rb") as f:
        try:
            for schema, channel, message in NonSeekingReader(f).iter_messages(log_time_order=False):
                streamed[channel.topic] = streamed.get(channel.topic, 0) + 1
            out["stream_complete"] = True
        except Exception as e:
            out["stream_complete"] = False
            out["stream_error"] = type(e).__name__ + ": " + str(e)
    out["streamed"] = streamed
    print(json.dumps(out, sort_keys=True))


if __name__ == "__main__":
    main(sys.argv[1])
